"""The README's topic table is the one the contract module generates."""
from pathlib import Path

from fall_predictor.wire import topics_markdown_table


def test_readme_topic_table_matches_the_contract():
    readme = (Path(__file__).parents[1] / 'README.md').read_text()
    assert topics_markdown_table() in readme
