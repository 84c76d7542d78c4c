"""Reading pickled ``.npy`` clips without running code: a restricted unpickler.

``np.load(path, allow_pickle=True)`` runs whatever callables the file's pickle names, so a crafted
clip could call ``os.system``. A poselib ``SkeletonMotion`` saved with ``np.save`` is a 0-d object
array holding a dict of plain containers, numpy arrays, dtypes and scalars; ``SafeUnpickler``
resolves only the globals those need (an explicit whitelist, each wrapped so that it accepts only
what numpy itself writes) and refuses every other global by name before anything is called.
``load_pickled_npy`` reads the ``.npy`` header with ``numpy.lib.format`` and unpickles the payload
through it.

What the shared poselib clips need (measured): ``collections.OrderedDict``, ``numpy.dtype``,
``numpy.ndarray`` (as the array type only) and ``numpy.core.multiarray._reconstruct`` /
``scalar``; numpy 2 writes ``numpy._core...`` and, with pickle protocol 5, ``numpy._core.numeric
._frombuffer``; protocol 2 writes bytes as ``_codecs.encode(text, "latin1")``.
"""

from __future__ import annotations

import collections
import math
import os
import pickle

import numpy as np
from numpy.lib import format as npy_format

_HARMLESS = {
    ("collections", "OrderedDict"): collections.OrderedDict,
    ("builtins", "set"): set,
    ("builtins", "frozenset"): frozenset,
    ("builtins", "complex"): complex,
    ("builtins", "bytearray"): bytearray,
    ("numpy", "dtype"): np.dtype,
}
# Python 2 pickles name these modules differently (what ``fix_imports`` maps).
_PY2_MODULES = {"__builtin__": "builtins", "copy_reg": "copyreg"}
_NUMPY_CORE = ("numpy.core.multiarray", "numpy._core.multiarray", "numpy.core.numeric", "numpy._core.numeric")


class RefusedPickle(pickle.UnpicklingError):
    """The file's pickle names a global outside the whitelist (or misuses one on it)."""


class NotPickledObject(ValueError):
    """The ``.npy`` file holds a plain array (or several objects), not one pickled object."""


class _NdarrayType:
    """Stands for ``numpy.ndarray`` in a pickle: the type argument of ``_reconstruct``, never
    called itself (``numpy.ndarray(shape)`` would allocate any size a file asks for)."""

    __slots__ = ()

    def __call__(self, *args, **kwargs):
        raise _refuse("a call of numpy.ndarray (arrays come only from numpy's own reconstructors)")


def _refuse(what: str) -> RefusedPickle:
    return RefusedPickle(f"refusing to unpickle {what}: a clip may hold only containers, numpy arrays and scalars")


def _numpy_reconstructors() -> tuple:
    """numpy's own pickle callables, found the way numpy uses them (their module moved in numpy 2)."""
    reconstruct = np.zeros(0).__reduce__()[0]
    scalar = np.float64(0).__reduce__()[0]
    frombuffer = np.zeros(1).__reduce_ex__(5)[0]
    return reconstruct, scalar, frombuffer


def _guarded(module: str, name: str):
    """A fresh, argument-checking wrapper for one whitelisted numpy callable (fresh per lookup so
    that a pickle's BUILD on it changes nothing beyond this one load), or None if not whitelisted."""
    reconstruct, scalar, frombuffer = _numpy_reconstructors()
    if module in _NUMPY_CORE and name == "_reconstruct":

        def _reconstruct(subtype, shape, dtype):
            """An empty array that the pickle's state then fills (numpy writes shape (0,))."""
            if not isinstance(subtype, _NdarrayType):
                raise _refuse(f"{module}.{name} of {type(subtype).__name__}")
            if not (isinstance(shape, tuple) and all(isinstance(n, int) for n in shape) and math.prod(shape) == 0):
                raise _refuse(f"{module}.{name} with shape {shape!r} (numpy writes empty arrays here)")
            return reconstruct(np.ndarray, shape, dtype)

        return _reconstruct
    if module in _NUMPY_CORE and name == "scalar":

        def _scalar(dtype, *data):
            """A numpy scalar from its dtype and raw bytes (numpy checks the size)."""
            if not isinstance(dtype, np.dtype):
                raise _refuse(f"{module}.{name} of {type(dtype).__name__}")
            return scalar(dtype, *data)

        return _scalar
    if module in _NUMPY_CORE and name == "_frombuffer":

        def _frombuffer(buf, dtype, shape, order):
            """An array over the pickle's own bytes (protocol 5); numpy checks sizes and refuses objects."""
            if not isinstance(buf, (bytes, bytearray)) or not isinstance(dtype, np.dtype):
                raise _refuse(f"{module}.{name} of {type(buf).__name__}")
            return frombuffer(buf, dtype, shape, order)

        return _frombuffer
    if module == "_codecs" and name == "encode":

        def _encode(text, encoding="latin1"):
            """Bytes as protocol 2 writes them: ``encode(text, "latin1")`` only."""
            if not isinstance(text, str) or str(encoding).lower().replace("-", "") != "latin1":
                raise _refuse(f"_codecs.encode with encoding {encoding!r}")
            return text.encode("latin1")

        return _encode
    return None


class SafeUnpickler(pickle.Unpickler):
    """Unpickles only plain data: containers, numpy arrays, dtypes and scalars.

    ``find_class`` is the one place a pickle reaches a callable; it returns a whitelisted type or
    a guarded numpy reconstructor, and raises ``RefusedPickle`` naming any other ``module.name``.
    Persistent ids are refused by ``pickle.Unpickler`` itself.
    """

    def find_class(self, module: str, name: str):
        module = _PY2_MODULES.get(module, module)
        if (module, name) in _HARMLESS:
            return _HARMLESS[(module, name)]
        if (module, name) == ("numpy", "ndarray"):
            return _NdarrayType()
        fn = _guarded(module, name)
        if fn is None:
            raise _refuse(f"{module}.{name}")
        return fn


def _read_header(f) -> tuple[tuple[int, ...], bool, np.dtype]:
    """The ``.npy`` header (shape, fortran order, dtype), parsed by numpy without evaluating code."""
    version = npy_format.read_magic(f)
    if version == (1, 0):
        return npy_format.read_array_header_1_0(f)
    if version == (2, 0):
        return npy_format.read_array_header_2_0(f)
    raise ValueError(f".npy format version {version[0]}.{version[1]} (poselib clips are 1.0 or 2.0)")


def load_pickled_npy(path: str | os.PathLike) -> object:
    """The object inside a ``.npy`` file holding one pickled object (what ``np.save`` writes for a
    dict), unpickled by ``SafeUnpickler``.

    Raises:
        RefusedPickle: the pickle names a callable outside the whitelist (nothing was called).
        NotPickledObject: not a 0-d object array (e.g. a plain float array).
        ValueError: not a ``.npy`` file (bad magic string or header).
        Exception: whatever a truncated or malformed pickle raises (the caller reports it).
    """
    with open(path, "rb") as f:
        shape, _, dtype = _read_header(f)
        if dtype != np.dtype(object) or shape != ():
            raise NotPickledObject(f"{'an' if str(dtype)[0] in 'aeiou' else 'a'} {dtype} array of shape {shape}")
        arr = SafeUnpickler(f, encoding="latin1").load()
    if not (isinstance(arr, np.ndarray) and arr.dtype == object and arr.shape == ()):
        raise NotPickledObject(f"a pickled {type(arr).__name__}")
    return arr.item()
