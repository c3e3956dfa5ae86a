"""Laser line profile sensors (laser triangulation): profiles read and checked
(:mod:`~handeye.sensors.laser.profiles`) and fitted as sensor models (:mod:`~handeye.sensors.laser.model`)."""
