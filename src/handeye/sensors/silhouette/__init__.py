"""A fixed colour camera that sees the robot: the arm's meshes' silhouette against masks of it.

* :mod:`~handeye.sensors.silhouette.render`: the CPU renderer (projection, filling, distance fields);
* :mod:`~handeye.sensors.silhouette.model`: the posed arm and the sensor model the core fits;
* :mod:`~handeye.sensors.silhouette.start`: the camera's pose from the masks without a guess.
"""
