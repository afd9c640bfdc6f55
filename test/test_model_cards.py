"""The model cards (models/README.md): one per shipped model, its figures those of the JSON the
results page shows, the profiles' default models among them."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import yaml

from fall_predictor.profiles.profile import ProfileError, available_profiles, load_profile

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / 'models'
sys.path.insert(0, str(ROOT / 'scripts'))
import model_cards  # noqa: E402


def cards() -> dict:
    return yaml.safe_load((MODELS / 'cards.yaml').read_text())


def shipped() -> set[str]:
    return {p.name for p in MODELS.glob('*.json') if not p.name.endswith('.evaluation.json')}


def test_models_readme_is_what_the_cards_script_writes():
    assert (MODELS / 'README.md').read_text() == model_cards.render(), \
        'models/README.md is stale: run python scripts/model_cards.py'


def test_every_shipped_model_has_a_card_and_every_card_a_model():
    assert set(cards()) == shipped()


def test_each_profile_names_a_shipped_model_its_card_calls_the_default():
    entries = cards()
    for name in available_profiles():
        profile = load_profile(name)
        for controller in profile.controller_names:
            try:
                model = profile.model_for(controller)
            except ProfileError:            # C_bal on a robot whose profile ships no model for it
                continue
            assert model in entries, (name, controller, model)
            assert entries[model]['robot'] == name, (name, model)
        assert entries[profile.model_for()].get('default'), (name, profile.model_for())


def test_each_card_reports_the_evaluation_of_its_own_model_held_out():
    for name, entry in cards().items():
        evaluation = json.loads((ROOT / entry['heldout']).read_text())
        assert Path(evaluation['model']).name == name, (name, evaluation['model'])
        assert evaluation['trained_on_this_dataset'] is False, name
        fingerprint = json.loads((MODELS / name).read_text())['dataset_fingerprint']
        assert evaluation['dataset_fingerprint'] != fingerprint, name


def test_a_changed_figure_makes_the_cards_stale(tmp_path, monkeypatch):
    """The check can fail: an evaluation with one more false alarm changes the page."""
    entry = next(iter(cards().values()))
    evaluation = json.loads((ROOT / entry['heldout']).read_text())
    evaluation['n_false_positives'] += 1
    changed = tmp_path / 'evaluation.json'
    changed.write_text(json.dumps(evaluation))
    original = model_cards._load
    monkeypatch.setattr(model_cards, '_load', lambda path: (json.loads(changed.read_text())
                                                            if path == entry['heldout'] else original(path)))
    assert model_cards.render() != (MODELS / 'README.md').read_text()


def test_every_card_gives_the_models_cost_from_one_run_against_one_reference():
    """Each card's cost comes from the one run that timed every shipped model (bench_model_cost.py),
    its ratio to the reference model of that run; no card goes without one."""
    run = json.loads((ROOT / model_cards.COST).read_text())
    assert set(run['models']) == shipped()
    reference = run['models'][run['reference']]
    assert reference['ratio_to_reference'] == {'features_plus_predictor': 1.0, 'estimator': 1.0}
    for name, row in run['models'].items():
        for stage, key in (('features_plus_predictor', 'features_plus_predictor_us'),
                           ('estimator', 'estimator_us')):
            assert abs(row['ratio_to_reference'][stage] - row[key] / reference[key]) <= 0.006, (name, stage)
        assert row['robot'] == cards()[name]['robot'], name
    page = (MODELS / 'README.md').read_text()
    assert 'not measured' not in page
    assert page.count('- **Cost**: ') == len(shipped())
    assert page.count(f"× `{run['reference']}`'s in the same run") == len(shipped()) - 1


def test_a_card_with_a_second_held_out_measurement_shows_both_and_its_reading_first():
    for name, entry in cards().items():
        if not entry.get('remeasured'):
            continue
        again = json.loads((ROOT / entry['remeasured']).read_text())
        assert Path(again['model']).name == name and again['trained_on_this_dataset'] is False
        row = next(line for line in model_cards.summary_table(cards()).splitlines() if f'[`{name}`]' in line)
        assert f'{again["fpr"]:.3f} re-made' in row, row
        if entry.get('read_fpr_as'):
            assert f'| {entry["read_fpr_as"]}: ' in row, row


def test_each_cards_per_cause_figures_are_its_own_model_held_out():
    """A card's per-cause figures (cards.yaml ``causes:``) are evaluations of that very model on
    runs it was not trained on; every shipped model has them (the push-only ones on every cause)."""
    for name, entry in cards().items():
        parts = entry.get('causes') or {}
        assert 'nominal' in parts, name
        fingerprint = json.loads((MODELS / name).read_text())['dataset_fingerprint']
        for key, part in parts.items():
            evaluation = json.loads((ROOT / part['evaluation']).read_text())
            assert Path(evaluation['model']).name == name, (name, part['evaluation'])
            assert evaluation['trained_on_this_dataset'] is False, name
            assert evaluation['dataset_fingerprint'] != fingerprint, name
            causes = set(evaluation['deployment']['by_cause'])
            if key == 'walking':             # hours of walking, no disturbance
                assert evaluation['deployment']['walking']['hours'] > 0, name
            else:
                assert causes - {'walk'}, part['evaluation']
