"""The ``fall-predictor`` command line: one module per command group (``simulation``, ``dataset``,
``learning``, ``sweep``, ``robot``, ``bag``, ``estimation``), the shared argument types in ``args``.

May import: ``monitor``, ``contract``, ``data``, ``profiles``; ``robot``, ``sim``, ``learning`` and
``ros`` only inside a command's function, so ``fall-predictor --help`` loads none of them.
"""
from fall_predictor.cli.main import build_parser, main

__all__ = ['build_parser', 'main']
