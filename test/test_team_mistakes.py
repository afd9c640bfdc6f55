"""Each mistake of a team's files (team_mistakes.py: a shipped profile copied and changed) meets
its command and is said in one line on stderr naming the file and the field, exit 2 (``check``:
a ✗ row naming them, exit 1; a run that only a simulation shows wrong: exit 0 and one warning);
never a traceback, never a run that ends without a word."""
from __future__ import annotations

import sys

import pytest

from fall_predictor.cli.main import main
from team_mistakes import MISTAKES, Mistake, named, stderr_lines


def _run(mistake: Mistake, tmp_path, capsys) -> tuple[int, str, list[str]]:
    _, argv = mistake.make(tmp_path)
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, stderr_lines(err)


@pytest.mark.parametrize('mistake', [pytest.param(m, id=m.name, marks=[pytest.mark.slow] if m.slow else [])
                                     for m in MISTAKES])
def test_a_mistake_is_one_line_naming_the_file_and_the_field(mistake, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code, out, err = _run(mistake, tmp_path, capsys)
    except SystemExit as exit_:                        # the argument parser's refusal
        code, out, err = exit_.code, '', stderr_lines(capsys.readouterr().err)
    assert code == mistake.exit_code, (code, out, err)
    if mistake.is_check:                               # a table with the failing row
        assert '✗' in out and named(mistake, out), out
    else:
        assert len(err) == 1, err
        assert named(mistake, err[0]), err[0]
        assert 'Traceback' not in err[0]


def test_debug_keeps_the_traceback(tmp_path, capsys) -> None:
    mistake = next(m for m in MISTAKES if m.name == 'network_empty')
    _, argv = mistake.make(tmp_path)
    from fall_predictor.errors import TeamFileError
    with pytest.raises(TeamFileError, match='motion.pt'):
        main(argv + ['--debug'])


def test_an_unexpected_error_is_one_line_with_exit_1(monkeypatch, capsys) -> None:
    """A bug (not a mistake in a file) is one line too, naming its type and how to see more."""
    import fall_predictor.sim.checks as checks

    def broken(robot, controller=None):
        raise KeyError('a bug')
    monkeypatch.setattr(checks, 'static_checks', broken)
    assert main(['check', '--robot', 'g1']) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and 'internal error: KeyError' in err[0] and '--debug' in err[0]


def test_the_argument_parser_says_one_line(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(['simulate', '--duration', 'soon'])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and '--duration' in err[0] and '--help' in err[0]


if __name__ == '__main__':
    sys.exit(pytest.main([__file__, '-q']))
