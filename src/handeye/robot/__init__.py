"""The robot: arms' kinematic tables and their forward kinematics (:mod:`~handeye.robot.kinematics`),
URDFs read into such tables and written from them (:mod:`~handeye.robot.urdf`), and the robot models a
calibration takes the flange poses from (:mod:`~handeye.robot.models`)."""
