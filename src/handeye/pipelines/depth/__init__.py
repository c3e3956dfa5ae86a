"""A depth camera, everything but its mathematics (that is :mod:`handeye.sensors.depth`); its
registration is in :mod:`handeye.pipelines.kinds`.

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

__all__: list[str] = []  # its modules are its face; its registration is in handeye.pipelines.kinds

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
