"""The pipelines, each a folder or arrays to one :class:`~handeye.result.Calibration`: poses and images
(:mod:`~handeye.pipelines.calibration`), joint angles (:mod:`~handeye.pipelines.joints`), streams on two
clocks (:mod:`~handeye.pipelines.streams`), any folder the one way (:mod:`~handeye.pipelines.folders`), and a
second capture against a result (:mod:`~handeye.pipelines.verify`); then one package per kind of sensor
(``depth/``, ``laser/``, ``linescan/``, ``silhouette/``, ``rig/``: everything of it but its mathematics,
which is ``sensors/<kind>/``), each registered in :mod:`~handeye.pipelines.kinds`."""
