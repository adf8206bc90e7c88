"""The core type: exact quasi-rational transfer functions."""

from .quasipoly import QuasiPolynomial
from .transfer import TransferFunction, as_transfer, delay

__all__ = ["QuasiPolynomial", "TransferFunction", "as_transfer", "delay"]
