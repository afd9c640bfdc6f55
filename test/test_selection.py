"""Choosing among predictors (fall_predictor.learning.selection): the area under the Pareto
front and the analogues of the paper's FP-L1..3."""
import pytest

from fall_predictor.learning.selection import (PAPER_PREDICTORS, pareto_mean_lead,
                                               select_paper_analogues)

from learning_fixtures import sweep_point as point


def test_pareto_mean_lead_is_the_area_under_the_front():
    points = [point(0.0, 0.2), point(0.25, 0.6), point(0.3, 0.5), point(0.6, 0.9)]
    # best lead 0.2 on [0, 0.25), 0.6 on [0.25, 0.5]: (0.05 + 0.15) / 0.5
    assert pareto_mean_lead(points) == pytest.approx(0.4)
    assert pareto_mean_lead([point(0.1, 1.0)], max_fpr=0.5) == pytest.approx(0.8)
    assert pareto_mean_lead([]) == 0.0
    with pytest.raises(ValueError):
        pareto_mean_lead(points, max_fpr=0.0)


def test_paper_analogues_take_the_longest_lead_within_the_papers_fpr():
    points = [point(0.0, 0.3, 0.5), point(0.04, 0.7, 0.0), point(0.3, 0.9, -0.5),
              point(0.8, 1.2, -1.5), point(0.35, 0.8, -0.25)]
    chosen = {paper.name: p for paper, p in select_paper_analogues(points)}
    assert chosen['FP-L1'].tau_plus_s == -0.5        # FPR 0.3 <= 0.46, longest lead
    assert chosen['FP-L2'].tau_plus_s == 0.0         # FPR 0.04 <= 0.06
    assert chosen['FP-L3'].tau_plus_s == 0.5         # only FPR 0 <= 0.005
    high_fpr_only = [point(0.2, 0.5)]
    assert select_paper_analogues(high_fpr_only)[2][1].fpr == 0.2   # none qualifies: lowest FPR
    assert select_paper_analogues([]) == []
    assert [paper.name for paper in PAPER_PREDICTORS] == ['FP-L1', 'FP-L2', 'FP-L3']
