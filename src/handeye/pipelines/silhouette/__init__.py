"""A colour camera fixed in the cell that sees the arm itself (markerless: the arm's silhouette against
masks), everything but its mathematics (that is :mod:`handeye.sensors.silhouette`); its registration is in
:mod:`handeye.pipelines.kinds`.

* :mod:`~handeye.pipelines.silhouette.session`: a silhouette session's ``silhouette:`` section, its masks and joint angles;
* :mod:`~handeye.pipelines.silhouette.pipeline`: a start with no guess, outline rounds, then the estimation core;
* :mod:`~handeye.pipelines.silhouette.simulate`: masks of a Panda from a fixed camera, with a segmentation's errors.

``handeye.pipelines.silhouette`` was the pipeline's module: its names still import from here, with a
DeprecationWarning, for one release.
"""

from __future__ import annotations

from ..._shared.moved import forward_names

__all__: list[str] = []  # its modules are its face; its registration is in handeye.pipelines.kinds

__getattr__ = forward_names(__name__)  # the pipeline's names, from when this was its module
