"""Workflows around calibrations: capture loops and their robot and camera backends
(:mod:`~handeye.workflows.acquire`), many sessions at once (:mod:`~handeye.workflows.fleet`), and the
thesis's Monte-Carlo study (:mod:`~handeye.workflows.study`)."""
