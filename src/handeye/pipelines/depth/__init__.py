"""A depth camera, everything but its mathematics (that is :mod:`handeye.sensors.depth`), and its
registration (:data:`KIND`).

* :mod:`~handeye.pipelines.depth.session`: a depth session's ``depth:`` section, its clouds, its target (a board,
  balls, a mesh, the arm itself, or whatever the camera sees);
* :mod:`~handeye.pipelines.depth.pipeline`: a board's corners or the balls' centres measured in each cloud, then the
  estimation core; a mesh (:mod:`~handeye.pipelines.depth.mesh`), the arm (:mod:`~handeye.pipelines.depth.arm`) and a
  scene (:mod:`~handeye.pipelines.depth.scene`) each their own way;
* ``simulate_board``, ``simulate_mesh``, ``simulate_arm``, ``simulate_scene``: clouds of each target, with ground
  truth; :mod:`~handeye.pipelines.depth.simulate` chooses among them for ``handeye simulate --sensor depth``.

``handeye.pipelines.depth`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names
from ..sensor_kind import SensorKind

__all__ = ["KIND"]

#: The depth camera's registration (:mod:`handeye.pipelines.kinds`).
KIND = SensorKind(
    section="depth", cli="depth", display="depth camera", package=__name__,
    calibrate="pipeline:calibrate_depth_session", extras="session:extras", rig_member="pipeline:rig_member",
    rig_extras="session:rig_extras", simulate="simulate:simulate_command",
    targets=("mesh", "sphere", "arm", "scene"),
    simulate_help="a depth camera's 640x480 clouds of a mesh (--target mesh, the default: a flange-sized disc on the "
    "flange), a ball (sphere), a board, the arm itself (arm: markerless, its joint angles, always eye_to_hand; --arm "
    "panda, the arm with meshes) or an irregular object (scene: no target and no mesh given, X from the clouds' agreement)",
)

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
