"""The estimation core: the pose check and its verdict's evidence (:mod:`~handeye.estimation.diagnostics`),
held-out errors and the jackknife (:mod:`~handeye.estimation.validation`), the estimators and the choice
between them (:mod:`~handeye.estimation.estimators`), partly determined X (:mod:`~handeye.estimation.partial`),
two clocks (:mod:`~handeye.estimation.sync`) and the verdict (:mod:`~handeye.estimation.verdict`)."""
