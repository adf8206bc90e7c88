"""The core type: exact quasi-rational transfer functions."""

from .quasipoly import QuasiPolynomial
from .removable import removable_points
from .transfer import TransferFunction, as_transfer, delay

__all__ = ["QuasiPolynomial", "TransferFunction", "as_transfer", "delay", "removable_points"]
