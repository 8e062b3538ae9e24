"""Warp kernels of aca_warp, one module per stage, each kernel beside its thin launch wrapper.

Shipped as the subpackage ``aca_warp.kernels`` (see pyproject.toml). Every module sets
``enable_backward=False``; kernels are generic over float32/float64 with explicit overloads.
"""
