"""A colour camera fixed in the cell that sees the arm itself (markerless: the arm's silhouette against
masks), everything but its mathematics (that is :mod:`handeye.sensors.silhouette`), and its registration
(:data:`KIND`).

* :mod:`~handeye.pipelines.silhouette.session`: a silhouette session's ``silhouette:`` section, its masks and joint angles;
* :mod:`~handeye.pipelines.silhouette.pipeline`: a start with no guess, outline rounds, then the estimation core;
* :mod:`~handeye.pipelines.silhouette.simulate`: masks of a Panda from a fixed camera, with a segmentation's errors.

``handeye.pipelines.silhouette`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names
from ..sensor_kind import SensorKind

__all__ = ["KIND"]

#: The markerless colour camera's registration (:mod:`handeye.pipelines.kinds`).
KIND = SensorKind(
    section="silhouette", cli="silhouette", display="colour camera", package=__name__,
    calibrate="pipeline:calibrate_silhouette_session", extras="session:extras", simulate="simulate:simulate_command",
    simulate_help="a fixed colour camera's masks of a Panda (markerless, its joint angles, eye_to_hand; --poses of them)",
)

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
