"""The sweep's figures (fall_predictor.learning.plots), from a hand-made sweep result."""
from fall_predictor.learning.plots import plot_sweep

from learning_fixtures import sweep_result

PNG = b'\x89PNG\r\n\x1a\n'


def plot(result, out_dir):
    return plot_sweep(out_dir, result.points, result.pareto, result.selected,
                      result.learning_curve, result.baselines, result.config)


def test_plot_sweep_writes_the_figures_and_nothing_else(tmp_path):
    paths = plot(sweep_result(), tmp_path)
    names = ['fig10_tradeoff.png', 'fig11_parameters.png', 'fig11_learning_curve.png']
    assert paths == [tmp_path / name for name in names]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)    # no temporary file left
    for path in paths:
        assert path.read_bytes()[:8] == PNG


def test_without_a_learning_curve_there_is_no_learning_curve_figure(tmp_path):
    paths = plot(sweep_result(with_learning_curve=False), tmp_path)
    assert [p.name for p in paths] == ['fig10_tradeoff.png', 'fig11_parameters.png']
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
