"""A TorchScript archive (``torch.jit.save``) read into plain Python and numpy, without torch.

A team's learned policy usually comes as a TorchScript file (``policy.pt``, exported with
``torch.jit.script`` or ``torch.jit.trace``). Its weights can be read without torch, since the
file is a zip archive of plain parts:

* ``<root>/data.pkl``: the module tree, pickled (protocol 2). Each module is an object of a class
  named ``__torch__.<python module>.<class>`` (``__torch__.torch.nn.modules.rnn.LSTM``; a class
  TorchScript compiled twice gets a ``___torch_mangle_<N>`` module part); its state is a dict of
  its attributes in the order of the module's ``__dict__``: parameters, buffers, sub-modules and
  plain values (``training``, floats, strings, lists);
* ``<root>/data/<key>``: one file per tensor storage, its raw little-endian bytes (``byteorder``
  says otherwise on a big-endian writer). A tensor is pickled as ``torch._utils._rebuild_tensor_v2``
  applied to (storage, offset, shape, strides, ...), the storage as a persistent id
  ``('storage', torch.FloatStorage, key, device, numel)``; tensors may share a storage;
* ``<root>/code/__torch__/...``: the compiled Python source of each class. Hyper-parameters that
  TorchScript folds into the code rather than storing as attributes (``Final`` constants: an
  LSTM's ``hidden_size`` and ``num_layers``, an ELU's ``alpha``, a LeakyReLU's
  ``negative_slope``) are read from there, as :attr:`ScriptModule.constants`.

:func:`read_torchscript` reads the tree with a restricted unpickler: only the globals above map
to anything (each to a plain Python object), every other global is refused, so no code of the
file is ever run. Tensors become numpy arrays of the storage's dtype (bfloat16, which numpy lacks,
becomes float32 exactly), shape, strides and offset, copied out so each owns its memory. Anything
else (not a zip, a ``torch.save`` checkpoint instead of a TorchScript module, an unknown global or
storage type, a storage file of the wrong size) is a :class:`TorchScriptError` naming the file.
"""
from __future__ import annotations

import ast
import io
import pickle
import re
import zipfile
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Union

import numpy as np

from fall_predictor.errors import TeamFileError


class TorchScriptError(TeamFileError):
    """The file is not a TorchScript archive, or holds something this reader does not support;
    the message names the file and what is wrong."""


#: Storage class of the pickle -> numpy dtype of its bytes ('bfloat16': uint16 words, see
#: :func:`_storage_array`).
STORAGE_DTYPES: dict[str, str] = {
    'FloatStorage': 'float32', 'DoubleStorage': 'float64', 'HalfStorage': 'float16',
    'BFloat16Storage': 'bfloat16', 'LongStorage': 'int64', 'IntStorage': 'int32',
    'ShortStorage': 'int16', 'CharStorage': 'int8', 'ByteStorage': 'uint8', 'BoolStorage': 'bool',
    'ComplexFloatStorage': 'complex64', 'ComplexDoubleStorage': 'complex128',
}


@dataclass(frozen=True)
class ScriptModule:
    """One object of the module tree: a ``torch.nn.Module`` (or a TorchScript class object).

    ``attributes`` holds its attributes in pickle order: numpy arrays for tensors,
    :class:`ScriptModule` for sub-modules, plain values otherwise (a tensor parameter that is
    ``None``, such as a Linear without bias, is ``None``). ``code`` is its class's compiled source
    in the archive and ``constants`` that code's ``Final`` class constants (``torch.jit.script``
    declares them; ``torch.jit.trace`` does not: a traced layer's hyper-parameters are literals in
    its ``forward``, such as ``torch.elu(argument_1, 0.7)``).
    """

    qualified_name: str
    attributes: dict[str, Any] = field(default_factory=dict)
    constants: dict[str, Any] = field(default_factory=dict)
    code: str = field(default='', repr=False)

    @property
    def type_name(self) -> str:
        """The class name alone: ``'LSTM'`` for ``__torch__.torch.nn.modules.rnn.LSTM``."""
        return self.qualified_name.rsplit('.', 1)[-1]

    @property
    def python_module(self) -> str:
        """The Python module of the class, without ``__torch__.`` and mangling parts:
        ``'torch.nn.modules.linear'`` for ``__torch__.torch.nn.modules.linear.___torch_mangle_0.Linear``."""
        parts = self.qualified_name.split('.')[:-1]
        return '.'.join(p for p in parts if p != '__torch__' and not p.startswith('___torch_mangle'))

    def modules(self) -> Iterator[tuple[str, 'ScriptModule']]:
        """(name, sub-module) of each direct sub-module, in attribute order."""
        return ((k, v) for k, v in self.attributes.items() if isinstance(v, ScriptModule))

    def tensors(self) -> Iterator[tuple[str, np.ndarray]]:
        """(name, array) of each tensor attribute (parameters and buffers), in attribute order."""
        return ((k, v) for k, v in self.attributes.items() if isinstance(v, np.ndarray))

    def describe_tree(self, name: str = '', indent: int = 0) -> str:
        """The tree, one module a line, its tensors with their shapes: for error messages."""
        shapes = ', '.join(f'{k}{list(v.shape)}' for k, v in self.tensors())
        line = ' ' * indent + f'{name or "<root>"}: {self.type_name}' + (f' ({shapes})' if shapes else '')
        return '\n'.join([line] + [m.describe_tree(k, indent + 2) for k, m in self.modules()])


@dataclass(frozen=True)
class TorchScriptArchive:
    """What :func:`read_torchscript` read: the file, the archive's root folder, its format
    version and the module tree."""

    path: Path
    root: str
    version: int
    module: ScriptModule


# -- the restricted unpickler --------------------------------------------------------------------

class _Pickled:
    """Stand-in for a ``__torch__`` class while unpickling: keeps the state BUILD gives it."""

    qualified_name = ''

    def __setstate__(self, state: Any) -> None:
        self.state = state


@dataclass(frozen=True)
class _StorageType:
    name: str
    dtype: str


def _rebuild_tensor(storage: np.ndarray, offset: int, size: tuple, stride: tuple, *_: Any) -> np.ndarray:
    size, stride = tuple(int(s) for s in size), tuple(int(s) for s in stride)
    if len(size) != len(stride) or offset < 0 or any(s < 0 for s in size + stride):
        raise ValueError(f'tensor of shape {size}, strides {stride}, offset {offset}')
    if 0 not in size:
        last = offset + sum((n - 1) * s for n, s in zip(size, stride))
        if last >= storage.size:
            raise ValueError(f'tensor of shape {size}, strides {stride}, offset {offset} reaches '
                             f'element {last} of a storage of {storage.size}')
    elif offset > storage.size:
        raise ValueError(f'empty tensor at offset {offset} of a storage of {storage.size}')
    itemsize = storage.itemsize
    view = np.lib.stride_tricks.as_strided(storage[offset:], shape=size,
                                           strides=tuple(s * itemsize for s in stride))
    return np.array(view, copy=True)


def _rebuild_parameter(data: np.ndarray, *_: Any) -> np.ndarray:
    return data


def _restore_type_tag(value: Any, _type: str) -> Any:
    return value


def _as_list(data: Any) -> list:
    return list(data)


#: (module, name) of every global the reader accepts -> what it becomes.
_GLOBALS: dict[tuple[str, str], Any] = {
    ('torch._utils', '_rebuild_tensor_v2'): _rebuild_tensor,
    ('torch._utils', '_rebuild_tensor'): _rebuild_tensor,
    ('torch._utils', '_rebuild_parameter'): _rebuild_parameter,
    ('torch._utils', '_rebuild_parameter_with_state'): _rebuild_parameter,
    ('collections', 'OrderedDict'): OrderedDict,
    ('torch.jit._pickle', 'restore_type_tag'): _restore_type_tag,
    ('torch.jit._pickle', 'build_tensorlist'): _as_list,
    ('torch.jit._pickle', 'build_intlist'): _as_list,
    ('torch.jit._pickle', 'build_doublelist'): _as_list,
    ('torch.jit._pickle', 'build_boollist'): _as_list,
}


class _Unpickler(pickle.Unpickler):
    """Maps the accepted globals (``_GLOBALS``, storage types, ``__torch__`` classes) to plain
    objects and refuses every other; reads each storage once (tensors may share it)."""

    def __init__(self, archive: zipfile.ZipFile, root: str, path: Path, data: bytes, big_endian: bool) -> None:
        super().__init__(io.BytesIO(data))
        self.archive, self.root, self.path, self.big_endian = archive, root, path, big_endian
        self.storages: dict[str, np.ndarray] = {}
        self.classes: dict[str, type] = {}

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _GLOBALS:
            return _GLOBALS[(module, name)]
        if module == 'torch' and name in STORAGE_DTYPES:
            return _StorageType(name, STORAGE_DTYPES[name])
        if module == '__torch__' or module.startswith('__torch__.'):
            qualified = f'{module}.{name}'
            if qualified not in self.classes:
                self.classes[qualified] = type(name, (_Pickled,), {'qualified_name': qualified})
            return self.classes[qualified]
        raise TorchScriptError(f'{self.path}: holds the global {module}.{name}, which this reader '
                               f'does not support (it reads tensors, module classes and lists)')

    def persistent_load(self, pid: Any) -> np.ndarray:
        if not (isinstance(pid, tuple) and len(pid) == 5 and pid[0] == 'storage'):
            raise TorchScriptError(f'{self.path}: unsupported persistent id {pid!r}')
        _, storage_type, key, location, numel = pid
        if not isinstance(storage_type, _StorageType):
            raise TorchScriptError(f'{self.path}: storage {key!r} of unsupported type {storage_type!r}')
        if key not in self.storages:
            self.storages[key] = _storage_array(self.archive, f'{self.root}/data/{key}', storage_type,
                                                int(numel), self.big_endian, self.path)
        return self.storages[key]


def _storage_array(archive: zipfile.ZipFile, name: str, storage_type: _StorageType, numel: int,
                   big_endian: bool, path: Path) -> np.ndarray:
    """The elements of one storage file as a 1-D numpy array of its dtype (bfloat16 -> float32)."""
    try:
        raw = archive.read(name)
    except KeyError:
        raise TorchScriptError(f'{path}: storage file {name!r} is missing') from None
    bfloat16 = storage_type.dtype == 'bfloat16'
    dtype = np.dtype('uint16' if bfloat16 else storage_type.dtype)
    if big_endian:
        dtype = dtype.newbyteorder('>')
    if len(raw) != numel * dtype.itemsize:
        raise TorchScriptError(f'{path}: storage file {name!r} has {len(raw)} bytes, but its '
                               f'{numel} {storage_type.dtype} elements need {numel * dtype.itemsize}')
    array = np.frombuffer(raw, dtype=dtype).astype(dtype.newbyteorder('='))
    if bfloat16:        # bfloat16 is the upper half of a float32: exact
        array = (array.astype(np.uint32) << 16).view(np.float32)
    return array


# -- the compiled code's constants ---------------------------------------------------------------

_CONSTANT = re.compile(r'^\s+(\w+)\s*:\s*Final\[[^\]]*\]\s*=\s*(.+?)\s*$', re.MULTILINE)


def _class_source(source: str, class_name: str) -> str:
    """The block of ``class class_name`` in a compiled TorchScript code file ('' if absent)."""
    lines: list[str] = []
    inside = False
    for line in source.splitlines():
        if line and not line[0].isspace():
            inside = re.match(rf'class {re.escape(class_name)}\b', line) is not None
        if inside:
            lines.append(line)
    return '\n'.join(lines)


def _class_constants(code: str) -> dict[str, Any]:
    """The ``name : Final[T] = value`` constants of a class's compiled code."""
    constants: dict[str, Any] = {}
    for name, text in _CONSTANT.findall(code):
        try:
            constants[name] = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            constants[name] = text     # kept as written (e.g. 'inf')
    return constants


# -- reading -------------------------------------------------------------------------------------

def read_torchscript(path: Union[str, Path]) -> TorchScriptArchive:
    """Read a TorchScript archive into a :class:`ScriptModule` tree (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise TorchScriptError(f'{path}: no such file')
    if not zipfile.is_zipfile(path):
        raise TorchScriptError(f'{path}: not a TorchScript archive (not a zip file; a TorchScript '
                               f'file is the zip torch.jit.save writes)')
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        roots = sorted({n.split('/')[0] for n in names if n.count('/') == 1 and n.endswith('/data.pkl')})
        if len(roots) != 1:
            raise TorchScriptError(f'{path}: a zip file, but not a TorchScript archive: expected one '
                                   f'<root>/data.pkl, found {len(roots)}')
        root = roots[0]
        if not any(n.startswith(f'{root}/code/') for n in names):
            raise TorchScriptError(f'{path}: a torch.save() file (weights without the module code), '
                                   f'not a TorchScript module: export the policy with '
                                   f'torch.jit.script or torch.jit.trace and save that')
        version = _small_text(archive, f'{root}/version', '0')
        byteorder = _small_text(archive, f'{root}/byteorder', 'little')
        if byteorder not in ('little', 'big') or not version.isdigit():
            raise TorchScriptError(f'{path}: unreadable version {version!r} or byteorder {byteorder!r}')
        unpickler = _Unpickler(archive, root, path, archive.read(f'{root}/data.pkl'), byteorder == 'big')
        try:
            raw = unpickler.load()
        except TorchScriptError:
            raise
        except (pickle.UnpicklingError, ValueError, TypeError, AttributeError, EOFError,
                IndexError, KeyError) as exc:
            raise TorchScriptError(f'{path}: {root}/data.pkl could not be read: {exc}') from exc
        sources: dict[str, str] = {}

        def code(python_module: str) -> str:
            if python_module not in sources:
                name = f'{root}/code/' + python_module.replace('.', '/') + '.py'
                sources[python_module] = archive.read(name).decode('utf-8', 'replace') if name in names else ''
            return sources[python_module]

        if not isinstance(raw, _Pickled):
            raise TorchScriptError(f'{path}: data.pkl holds a {type(raw).__name__}, not a module')
        module = _convert(raw, code)
    return TorchScriptArchive(path=path, root=root, version=int(version), module=module)


def _small_text(archive: zipfile.ZipFile, name: str, default: str) -> str:
    try:
        return archive.read(name).decode('ascii', 'replace').strip()
    except KeyError:
        return default


def _convert(value: Any, code: Callable[[str], str]) -> Any:
    """The unpickled tree with every stand-in object turned into a :class:`ScriptModule`."""
    if isinstance(value, _Pickled):
        state = getattr(value, 'state', {})
        attributes = ({str(k): _convert(v, code) for k, v in state.items()} if isinstance(state, dict)
                      else {'__state__': _convert(state, code)})
        module, _, name = value.qualified_name.rpartition('.')
        source = _class_source(code(module), name)
        return ScriptModule(value.qualified_name, attributes, _class_constants(source), source)
    if isinstance(value, list):
        return [_convert(v, code) for v in value]
    if isinstance(value, tuple):
        return tuple(_convert(v, code) for v in value)
    if isinstance(value, dict):
        return {k: _convert(v, code) for k, v in value.items()}
    return value
