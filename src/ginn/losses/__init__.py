"""Loss terms as small objects with explicit tensor inputs: the constraints of the paper's Table 1
(with eikonal, obstacle and strain), and the diversity of a set of shapes (Appendix E)."""

from .constraints import (
    DesignRegionLoss,
    EikonalLoss,
    InterfaceLoss,
    MeanCurvatureLoss,
    NormalLoss,
    ObstacleLoss,
    StrainLoss,
)
from .diversity import aggregate, aggregate_min, aggregate_sum, boundary_distances, cross_values, distance_matrix, diversity, mean_diversity

__all__ = [
    "DesignRegionLoss", "ObstacleLoss", "InterfaceLoss", "NormalLoss", "EikonalLoss", "MeanCurvatureLoss", "StrainLoss",
    "diversity", "aggregate", "aggregate_min", "aggregate_sum", "cross_values", "distance_matrix",
    "boundary_distances", "mean_diversity",
]
