"""The sensors: one package per kind, each saying what one view measured and how to predict it.

* :mod:`~handeye.sensors.camera`: area cameras (targets, detection, PnP, intrinsics, the renderer);
* :mod:`~handeye.sensors.depth`: depth cameras' clouds (boards' corners lifted to 3D, spheres);
* :mod:`~handeye.sensors.laser`: laser line profilers' profiles (a ball, a plate, ...);
* :mod:`~handeye.sensors.linescan`: line-scan cameras' pushbroom scans of a target swept by the robot.
"""
