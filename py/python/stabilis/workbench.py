"""The model workbench: compare a model with measured FRFs, see where it fails, discover the
missing physical effect, add it and watch the weighted error fall.

>>> import stabilis
>>> wb = stabilis.Workbench()          # the embedded flying-platform dataset
>>> result = wb.discover()
>>> result["found"]
['momentum_drag', 'fan_gyroscopic']
"""
from . import _stabilis

Workbench = _stabilis.workbench.Workbench

__all__ = ["Workbench"]
