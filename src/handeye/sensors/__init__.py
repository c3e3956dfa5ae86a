"""The sensors' mathematics: one package per kind, each saying what one view measured and how to predict
it (everything else of a kind, its sessions, pipeline, simulator and planner, is ``pipelines/<kind>/``).

* :mod:`~handeye.sensors.camera`: area cameras (targets, detection, PnP, intrinsics, the renderer);
* :mod:`~handeye.sensors.depth`: depth cameras' clouds (boards' corners lifted to 3D, spheres, meshes, the arm, a scene);
* :mod:`~handeye.sensors.laser`: laser line profilers' profiles (a ball, a plate, ...);
* :mod:`~handeye.sensors.linescan`: line-scan cameras' pushbroom scans of a target swept by the robot;
* :mod:`~handeye.sensors.silhouette`: a fixed colour camera's masks of the arm itself;
* :mod:`~handeye.sensors.rig`: several sensors on one robot as one model.
"""
