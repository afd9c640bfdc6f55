"""Learning and evaluation: hindsight labels and training weights (``labels``), the
decision-list learners (``learners``) and the boosted trees' (``boosting``), metrics such as FPR and tau_lead (``metrics``),
hand-coded baselines (``baselines``), training on a dataset (``training``), evaluating a model
on one (``evaluation``) and the deployer's figures per cause, impulse band and hour of walking
(``deployment``), what disturbed each run and the groups folds keep whole (``run_groups``),
cross-validation (``crossval``), choosing among predictors
(``selection``), the tau_plus x tau_his sweep (``sweep`` computes it, ``sweep_results`` holds
its settings and results as data), its report (``report``) and figures (``plots``,
``plots_intervals``), which read the results, and ``sweep_files``, which runs the sweep and
writes them.

May import: fall_predictor.monitor, fall_predictor.data, numpy, scipy (scikit-learn's own dependency), scikit-learn, joblib,
matplotlib, tqdm.
"""
