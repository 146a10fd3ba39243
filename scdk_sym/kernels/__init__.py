"""Numeric kernels of a model: its CasADi Functions, compiled C and the disk cache."""
