"""Learning and evaluation: hindsight labels and training weights (``labels``), the
decision-list learners (``learners``), metrics such as FPR and tau_lead (``metrics``),
hand-coded baselines (``baselines``), training on a dataset (``training``), evaluating a model
on one (``evaluation``), cross-validation (``crossval``), choosing among predictors
(``selection``), the tau_plus x tau_his sweep (``sweep``), and its report (``report``) and
figures (``plots``).

May import: fall_predictor.monitor, fall_predictor.data, numpy, scikit-learn, joblib,
matplotlib, tqdm.
"""
