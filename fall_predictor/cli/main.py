"""fall-predictor: offline tools of the fall_predictor package (simulate, generate, train, ...)."""
from __future__ import annotations

import argparse
import importlib
import signal
import sys
import warnings

#: The command groups, one module each under fall_predictor/cli/, each exposing
#: ``register(subparsers)``: each area's options live with its code.
COMMAND_MODULES: tuple[str, ...] = ('simulation', 'dataset', 'learning', 'sweep', 'robot', 'bag',
                                    'estimation', 'check')
#: Keeps the traceback of an error (anywhere on the command line).
DEBUG_FLAG = '--debug'


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose complaint is one line on stderr (exit 2), as every other error
    of the command is: the usage is one ``--help`` away."""

    def error(self, message: str):
        from fall_predictor.errors import one_line
        self.exit(2, f'{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n')


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog='fall-predictor', description=__doc__,
                           epilog=f'{DEBUG_FLAG} (anywhere): print the traceback of an error '
                                  'instead of its one line')
    sub = parser.add_subparsers(dest='command', metavar='<command>')
    for name in COMMAND_MODULES:
        importlib.import_module(f'fall_predictor.cli.{name}').register(sub)
    return parser


def _interrupt_on_sigterm(signum: int, frame: object) -> None:
    # As Ctrl-C: joblib then stops its worker processes instead of leaving them orphaned
    # (a killed generate is finished by running it again).
    raise KeyboardInterrupt(f'signal {signum}')


def main(argv: list[str] | None = None) -> int:
    if argv is None:                     # the process's own command line: it owns the signals
        signal.signal(signal.SIGTERM, _interrupt_on_sigterm)
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = DEBUG_FLAG in argv
    argv = [a for a in argv if a != DEBUG_FLAG]
    from fall_predictor.errors import set_debug
    set_debug(debug)
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv                                    # recorded by sweep
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    if getattr(args, 'push_force', 0) < 0:
        parser.error('--push-force must be >= 0')
    with warnings.catch_warnings():
        warnings.showwarning = _note            # data left out is said as a note, not a traceback
        try:
            return int(args.func(args) or 0)
        except Exception as error:              # noqa: BLE001 - one line, whatever it is
            if debug:
                raise
            # the sub-command's name (args.command may be an option of the same name)
            return _one_line_error(next(a for a in argv if not a.startswith('-')), error)


def _one_line_error(command: str, error: Exception) -> int:
    """Say ``error`` in one line on stderr: exit 2 for a mistake in a file or a setting the user
    gave (its message names the file and the field), 1 for anything else (a bug: its type and
    message, and how to see the traceback)."""
    from fall_predictor.errors import one_line
    kind = _user_error_kind(error)
    if kind is None:
        print(f'fall-predictor {command}: internal error: {type(error).__name__}: {one_line(error)} '
              f'(rerun with {DEBUG_FLAG} for the traceback, and report it)', file=sys.stderr)
        return 1
    print(f'fall-predictor {command}: error: {kind}{one_line(error)}', file=sys.stderr)
    return 2


def _user_error_kind(error: Exception) -> str | None:
    """'' (or a prefix saying what failed) when ``error`` is about a file or setting the user
    gave, None otherwise."""
    import json
    import xml.etree.ElementTree as ET

    import yaml

    from fall_predictor.errors import TeamFileError
    if isinstance(error, TeamFileError):
        return ''
    if isinstance(error, (json.JSONDecodeError, yaml.YAMLError, ET.ParseError, UnicodeDecodeError)):
        return 'a file cannot be parsed: '
    if isinstance(error, OSError):              # no such file, a folder for a file, permissions
        return ''
    known = []
    for module, name in (('fall_predictor.data.dataset', 'DatasetError'),
                         ('fall_predictor.data.bagio', 'BagError')):
        loaded = sys.modules.get(module)        # raised only if its module was loaded
        if loaded is not None:
            known.append(getattr(loaded, name))
    return '' if known and isinstance(error, tuple(known)) else None


def _note(message, category, filename, lineno, file=None, line=None) -> None:
    print(f'note: {message}', file=sys.stderr)


if __name__ == '__main__':
    sys.exit(main())
