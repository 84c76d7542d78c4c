"""Writing the exported function: ONNX (``jax2onnx``) or serialized StableHLO (``jax.export``).

Both converters are optional (``pip install .[export]``); a missing one is one clear line.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import jax

from jaxmotion.export.policy import ExportError, Layout

FORMATS = ("onnx", "stablehlo")
OPSET = 17
"""The ONNX opset written: onnxruntime 1.17 and later run it."""


def write_onnx(fn: Callable, layout: Layout, path: Path, name: str = "jaxmotion_policy") -> None:
    """``fn`` as an ONNX model at ``path`` with the layout's input and output names."""
    try:
        from jax2onnx import to_onnx
    except ImportError:
        raise ExportError("ONNX export needs jax2onnx: pip install '.[export]'") from None
    # jax2onnx 0.13.0 (the newest that installs beside jax 0.9.2) logs a traceback for each of its
    # plugins of linear-algebra primitives this jax lacks (ormqr); no policy uses them.
    plugins = logging.getLogger("jax2onnx.plugins.plugin_system")
    level = plugins.level
    plugins.setLevel(logging.ERROR)
    # jax2onnx traces the function; under JAX_DISABLE_JIT it would see concrete values instead.
    try:
        with jax.disable_jit(False):
            model = to_onnx(
                fn,
                layout.specs(),
                model_name=name,
                opset=OPSET,
                input_names=layout.input_names,
                output_names=layout.output_names,
            )
    finally:
        plugins.setLevel(level)
    path.write_bytes(model.SerializeToString())


def write_stablehlo(fn: Callable, layout: Layout, path: Path) -> None:
    """``fn`` as ``jax.export``'s serialized StableHLO at ``path`` (load it with
    ``jax.export.deserialize``; its ``call`` takes the layout's inputs in order)."""
    with jax.disable_jit(False):
        exported = jax.export.export(jax.jit(fn))(*layout.specs())
    path.write_bytes(exported.serialize())


def write(fmt: str, fn: Callable, layout: Layout, path: Path) -> None:
    if fmt == "onnx":
        write_onnx(fn, layout, path)
    else:
        write_stablehlo(fn, layout, path)
