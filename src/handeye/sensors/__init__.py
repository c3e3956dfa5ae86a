"""The sensors: one package per kind, each saying what one view measured and how to predict it.

* :mod:`~handeye.sensors.camera`: area cameras (targets, detection, PnP, intrinsics, the renderer);
* :mod:`~handeye.sensors.depth`: depth cameras' clouds (boards' corners lifted to 3D, spheres).
"""
