"""Files in: capture session folders (:mod:`~handeye.io.session`: a camera's, and what every kind's session
shares; each other kind of sensor reads its own section in ``pipelines/<kind>/session.py``), results read
back (:mod:`~handeye.io.results`) and other tools' captures (:mod:`~handeye.io.importers`)."""
