"""Neural-field models: every model is called as ``model(x, z)`` with ``x`` (n, d), ``z`` (n, k)."""

from .base import ConcatConditioning, Conditioning, IdentityEncoding, NeuralField, PeriodicEncoding
from .mlp import MLP, FourierFeatures, FourierMLP, ResMLP, make_activation
from .siren import SineLayer, Siren

__all__ = [
    "NeuralField",
    "Conditioning",
    "ConcatConditioning",
    "PeriodicEncoding",
    "IdentityEncoding",
    "Siren",
    "SineLayer",
    "MLP",
    "ResMLP",
    "FourierMLP",
    "FourierFeatures",
    "make_activation",
]
