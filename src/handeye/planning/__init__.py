"""Planning what to capture: robot poses that determine X well for a camera (:mod:`~handeye.planning.poses`,
``handeye plan``), a rig of cameras (:mod:`~handeye.planning.rig`), a laser line profiler
(:mod:`~handeye.planning.laser`) or a line-scan camera (:mod:`~handeye.planning.linescan`), and the joint
configurations that would determine what a joint fit left undetermined (:mod:`~handeye.planning.joints`)."""

from __future__ import annotations

from .joints import TABLE_DOMINATES, JointViews, suggest_joint_views
from .laser import LaserPlan, plan_laser
from .linescan import LineScanPlan, plan_linescan
from .poses import (
    ROBOTS,
    Plan,
    candidate_views,
    choose_next,
    choose_views,
    easy_handeye_poses,
    order_path,
    plan_poses,
    predicted_cov,
    reprojection_information,
    simulate_errors,
    visible_mask,
    write_plan,
)
from .rig import RigPlan, RigPlanCamera, plan_rig

__all__ = ["Plan", "ROBOTS", "plan_poses", "easy_handeye_poses", "reprojection_information", "predicted_cov",
           "visible_mask", "simulate_errors", "write_plan", "order_path", "candidate_views", "choose_next",
           "JointViews", "suggest_joint_views", "TABLE_DOMINATES", "LaserPlan", "plan_laser", "RigPlan", "RigPlanCamera",
           "plan_rig", "choose_views", "LineScanPlan", "plan_linescan"]
