"""Warp kernels of aca_warp, one module per stage, each kernel beside its thin launch wrapper.

Shipped as the subpackage ``aca_warp.kernels`` (see pyproject.toml). The physics that the HF engines' kernels share
are Warp functions with one home each in ``physics`` (friction law and sub-step, per-patch terms, contact, sample
sums). Every module sets ``enable_backward=False``. A kernel's parameters that belong together come as one Warp
struct, declared once: the HF model's arrays, the recorder's, the adaptive integrator's (``hf_types``), the LF
automaton's cells, rings and patches (``lf_types``). Kernels generic in the state precision T (``Any`` in their
annotations) get their float32 and float64 overloads from :func:`precision_overloads`; a struct with fields in T is
a :class:`PrecisionStruct`.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any

import warp as wp

PRECISIONS = (wp.float32, wp.float64)


def _concrete(annotation: Any, T: Any) -> Any:
    """``annotation`` with the precision placeholder ``Any`` replaced by ``T`` (scalars and array dtypes)."""
    if annotation is Any:
        return T
    if wp.types.is_array(annotation) and annotation.dtype is Any:
        return type(annotation)(dtype=T, ndim=annotation.ndim)
    return annotation


class PrecisionStruct:
    """A Warp struct generic in the state precision T, declared once as a class whose fields are annotated as a
    generic kernel's parameters are (``Any`` and ``wp.array[Any]`` stand for T and arrays of T).

    ``S(T)`` is the concrete ``wp.struct`` of precision T (``wp.float32`` or ``wp.float64``; named after the class
    with the bits appended); :meth:`of` fills one from arrays by field name. Warp structs cannot be generic, so a
    generic kernel or function takes the struct as a parameter annotated ``Any``: a function adapts to the struct
    it is called with, and a kernel names the struct of that parameter in its :func:`precision_overloads` call.
    """

    def __init__(self, cls: type) -> None:
        hints = inspect.get_annotations(cls, eval_str=True)
        self.__name__ = cls.__name__
        self.__doc__ = cls.__doc__
        self.fields = tuple(hints)
        self._structs = {}
        for T in PRECISIONS:
            name = f"{cls.__name__}{8 * wp.types.type_size_in_bytes(T)}"
            body = {k: _concrete(a, T) for k, a in hints.items()}
            namespace = {"__annotations__": body, "__module__": cls.__module__, "__qualname__": name}
            self._structs[T] = wp.struct(type(name, (), namespace))

    def __call__(self, T: Any) -> Any:
        """The concrete struct type of precision ``T``."""
        return self._structs[T]

    def of(self, T: Any, values: Mapping[str, Any]) -> Any:
        """A struct of precision ``T`` whose fields take ``values`` by name; a field missing there stays empty (a
        null array, a zero scalar) and must not be read."""
        s = self(T)()
        for k in self.fields:
            if k in values:
                setattr(s, k, values[k])
        return s


def precision_overloads(*kernels: Any, **structs: PrecisionStruct) -> None:
    """Declare the float32 and float64 overloads of generic kernels, read from their own annotations; a parameter
    named in ``structs`` (annotated ``Any``) takes that :class:`PrecisionStruct` of the overload's precision."""
    for kernel in kernels:
        for T in PRECISIONS:
            types = {name: structs[name](T) if name in structs else _concrete(t, T)
                     for name, t in kernel.adj.arg_types.items()}  # fmt: skip
            wp.overload(kernel, types)
