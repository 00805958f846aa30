"""stabilis: stabilizing unstable systems."""
from . import _stabilis  # noqa: F401
from ._stabilis import Error, LogError, ModelError, SimError
from . import geometry, log, sim
from . import cubli
from . import pmpc
from . import tilt
from .log import Log, read_csv, read_mcap
from . import workbench
from .workbench import Effect, Model, Workbench
from . import power_study
from .power_study import power
