"""Algebraic (polynomial) forms of closure systems, for complete solution by homotopy."""

from .certify import (
    Certificate,
    CertificateSet,
    certify_all,
    certify_configurations,
    certify_solution,
    closure_function,
    krawczyk,
)
from .interval import IntervalFunction, interval_function

__all__ = [
    "Certificate",
    "CertificateSet",
    "IntervalFunction",
    "certify_all",
    "certify_configurations",
    "certify_solution",
    "closure_function",
    "interval_function",
    "krawczyk",
]
