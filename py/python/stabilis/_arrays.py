"""Conversion of array arguments: anything ``numpy.asarray`` accepts, as float64, except values
of a complex, object, string or other non-numeric dtype, which are refused (TypeError naming the
argument and the dtype) instead of silently losing their imaginary part or being parsed.

``real_array`` is the native conversion (``py/src/real.rs``) that the workbench, the models'
callables and ``pmpc`` use too: one rule for every array the package takes. ``real_scalar(x,
name)`` applies it to a number argument (as the native functions do to theirs) where ``float``
would keep the real part of a numpy complex or parse a string: a complex number (even
``1+0j``), a string or an object is a TypeError naming ``name``."""
import numpy as np

from ._stabilis import real_array, real_scalar


def _complex(value):
    if isinstance(value, (complex, np.complexfloating)):
        return True
    if isinstance(value, np.ndarray):
        return np.iscomplexobj(value)
    if isinstance(value, (list, tuple)):
        return any(_complex(v) for v in value)
    return False


def real_arguments(function):
    """Wraps a native function so that a complex argument (number, list or array) is a
    TypeError naming it, instead of being converted through ``__float__``, which drops the
    imaginary part."""
    import functools

    @functools.wraps(function)
    def call(*args, **kwargs):
        for i, value in enumerate(args):
            if _complex(value):
                raise TypeError(f"argument {i} of {function.__name__} must be real; got complex values")
        for name, value in kwargs.items():
            if _complex(value):
                raise TypeError(f"{name} of {function.__name__} must be real; got complex values")
        return function(*args, **kwargs)

    return call
