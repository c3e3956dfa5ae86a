"""The pipelines, each a folder or arrays to one :class:`~handeye.result.Calibration`: poses and images
(:mod:`~handeye.pipelines.calibration`), joint angles (:mod:`~handeye.pipelines.joints`), streams on two
clocks (:mod:`~handeye.pipelines.streams`), depth clouds (:mod:`~handeye.pipelines.depth.pipeline`), any folder the
one way (:mod:`~handeye.pipelines.folders`), and a second capture against a result (:mod:`~handeye.pipelines.verify`)."""
