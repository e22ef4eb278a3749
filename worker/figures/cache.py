"""Figures drawn once per distinct input, then copied: a figure is a pure function of its runs (spec, status,
arrays, provenance) and of the drawing code, so a class whose submissions share the baseline runs draws their figures
once, and every later submission copies the same PNGs instead of drawing 18 figures (about 4 s) again.

An entry is a folder named by the SHA-256 of the figure's kind, the drawing code (every module of this package and
the matplotlib version) and each input run's digest. It holds the one PNG under its own file name and appears under
its final name only when complete (written beside, then renamed), so concurrent workers never read half a figure.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

from rubric import CaseResult

_PACKAGE = Path(__file__).parent


def _code_digest() -> str:
    digest = hashlib.sha256(matplotlib.__version__.encode())
    for source in sorted(_PACKAGE.glob("*.py")):
        digest.update(source.name.encode())
        digest.update(source.read_bytes())
    return digest.hexdigest()


CODE_DIGEST = _code_digest()


def result_digest(result: CaseResult) -> str:
    """What a figure can show of a run: its spec, outcome, provenance (the footer) and every array, byte for byte."""
    digest = hashlib.sha256()
    digest.update(result.spec.model_dump_json().encode())
    digest.update(f"{result.status}\0{result.error or ''}".encode())
    digest.update(result.provenance.model_dump_json().encode() if result.provenance else b"-")
    digest.update(result.metrics.model_dump_json().encode() if result.metrics else b"-")
    for name in sorted(result.arrays):
        array = result.arrays[name]
        digest.update(f"{name}\0{array.dtype.str}\0{array.shape}".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


class FigureCache:
    """Draw-or-copy for one submission's figures; root None draws every figure (no cache)."""

    def __init__(self, root: Path | None):
        self.root = Path(root) if root is not None else None
        self.drawn = 0
        self.copied = 0

    def figure(self, kind: str, inputs: Sequence[CaseResult], out_dir: Path, draw: Callable[[], Path]) -> Path:
        if self.root is None:
            self.drawn += 1
            return draw()
        key = hashlib.sha256("\0".join([kind, CODE_DIGEST, *map(result_digest, inputs)]).encode()).hexdigest()
        entry = self.root / key[:2] / key
        if entry.is_dir():
            (png,) = entry.iterdir()
            out_dir.mkdir(parents=True, exist_ok=True)
            target = out_dir / png.name
            shutil.copyfile(png, target)
            self.copied += 1
            return target
        path = draw()
        self.drawn += 1
        partial = entry.with_name(f"{key}.partial-{os.getpid()}")
        partial.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, partial / path.name)
        try:
            partial.rename(entry)
        except OSError:  # another worker stored the same figure first: its copy is identical
            shutil.rmtree(partial, ignore_errors=True)
        return path
