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
                                    'estimation')


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='fall-predictor', description=__doc__)
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
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)   # recorded by sweep
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    if getattr(args, 'push_force', 0) < 0:
        parser.error('--push-force must be >= 0')
    with warnings.catch_warnings():
        warnings.showwarning = _note            # data left out is said as a note, not a traceback
        return int(args.func(args) or 0)


def _note(message, category, filename, lineno, file=None, line=None) -> None:
    print(f'note: {message}', file=sys.stderr)


if __name__ == '__main__':
    sys.exit(main())
