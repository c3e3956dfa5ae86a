"""Files in: capture session folders (:mod:`~handeye.io.session`, :mod:`~handeye.pipelines.depth.session`) and
other tools' captures (:mod:`~handeye.io.importers`)."""
