"""Conversion of array arguments: anything ``numpy.asarray`` accepts, as float64, except complex
values, which are refused instead of silently losing their imaginary part."""
import numpy as np


def real_array(x, name="argument"):
    """``x`` as a C-contiguous float64 array; TypeError for complex input."""
    if np.iscomplexobj(x):
        raise TypeError(f"{name} must be real; got complex values (pass x.real to drop the imaginary part)")
    return np.ascontiguousarray(x, dtype=np.float64)


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
