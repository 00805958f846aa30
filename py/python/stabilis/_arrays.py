"""Conversion of array arguments: anything ``numpy.asarray`` accepts, as float64, except complex
values, which are refused instead of silently losing their imaginary part."""
import numpy as np


def real_array(x, name="argument"):
    """``x`` as a C-contiguous float64 array; TypeError for complex input."""
    if np.iscomplexobj(x):
        raise TypeError(f"{name} must be real; got complex values (pass x.real to drop the imaginary part)")
    return np.ascontiguousarray(x, dtype=np.float64)
