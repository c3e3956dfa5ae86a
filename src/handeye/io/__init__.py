"""Files in: capture session folders (:mod:`~handeye.io.session`, :mod:`~handeye.io.depth_session`) and
other tools' captures (:mod:`~handeye.io.importers`)."""
