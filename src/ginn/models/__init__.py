"""Neural-field models: every model is called as ``model(x, z)`` with ``x`` (n, d), ``z`` (n, k);
:func:`build_model` makes one from its config; the latent codes of generative models."""

from .base import ConcatConditioning, Conditioning, IdentityEncoding, NeuralField, PeriodicEncoding
from .factory import build_model
from .frame import DomainFrame
from .latents import fixed_latents, latent_dim, midpoints, random_latents
from .mlp import MLP, FourierFeatures, FourierMLP, ResMLP, make_activation
from .siren import SineLayer, Siren, compile_derivatives
from .symmetric import SymmetricField
from .wire import Wire

__all__ = [
    "NeuralField",
    "DomainFrame",
    "Conditioning",
    "ConcatConditioning",
    "PeriodicEncoding",
    "IdentityEncoding",
    "Siren",
    "SineLayer",
    "Wire",
    "SymmetricField",
    "MLP",
    "ResMLP",
    "FourierMLP",
    "FourierFeatures",
    "make_activation",
    "build_model",
    "compile_derivatives",
    "fixed_latents",
    "random_latents",
    "latent_dim",
    "midpoints",
]
