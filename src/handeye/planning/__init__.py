"""Planning what to capture: robot poses that determine X well for a camera (:mod:`~handeye.planning.poses`,
``handeye plan``), and the joint configurations that would determine what a joint fit left undetermined
(:mod:`~handeye.planning.joints`). Another kind of sensor plans in its own folder (``pipelines/<kind>/plan.py``:
a laser line profiler's, a line-scan camera's, a rig's); their old names here still import, with a
DeprecationWarning, for one release."""

from __future__ import annotations

from .._shared.moved import forward_names
from .joints import TABLE_DOMINATES, JointViews, suggest_joint_views
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

__all__ = ["Plan", "ROBOTS", "plan_poses", "easy_handeye_poses", "reprojection_information", "predicted_cov",
           "visible_mask", "simulate_errors", "write_plan", "order_path", "candidate_views", "choose_next",
           "JointViews", "suggest_joint_views", "TABLE_DOMINATES", "choose_views"]

__getattr__ = forward_names(__name__)  # the laser's, the line-scan camera's and the rig's planners, moved to their kinds' folders
