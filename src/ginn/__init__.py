"""ginn: geometry-informed neural networks."""

from . import fields
from .models import MLP, FourierMLP, NeuralField, PeriodicEncoding, ResMLP, Siren

__version__ = "0.1.0"

__all__ = ["fields", "NeuralField", "Siren", "ResMLP", "MLP", "FourierMLP", "PeriodicEncoding", "__version__"]
