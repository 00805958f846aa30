"""stabilis: stabilizing unstable systems."""
from . import _stabilis  # noqa: F401
