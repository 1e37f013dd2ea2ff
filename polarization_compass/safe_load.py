"""Loading files without executing them, and with one-line errors.

Everything the package reads from disk goes through here: ``.npz`` archives (numpy, never pickle),
YAML (``yaml.safe_load`` only) and text (UTF-8). Each function takes the error class of its caller
(a :class:`~polarization_compass.errors.CompassError`), so a bad file is a user error with a short
message, never a traceback, a leaked file handle or an ``internal error``.
"""
from __future__ import annotations

import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import yaml

from .errors import CompassError

__all__ = ["open_npz", "read_text", "load_yaml", "yaml_problem"]


def _existing_file(path, error, what) -> Path:
    """``path`` as a Path; ``error`` when it does not exist or is a directory."""
    p = Path(path)
    if not p.exists():
        raise error(f"{what} {str(p)!r} does not exist")
    if p.is_dir():
        raise error(f"{what} {str(p)!r} is a directory")
    return p


def read_text(path, error=CompassError, what="file") -> str:
    """The UTF-8 text of ``path``; missing, directory, unreadable or binary files raise ``error``."""
    p = _existing_file(path, error, what)
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{what} {str(p)!r} is not UTF-8 text (byte {exc.start}); is it the right file?") from None
    except OSError as exc:
        raise error(f"{what} {str(p)!r} cannot be read: {exc.strerror}") from None


def yaml_problem(exc: yaml.YAMLError) -> str:
    """One line from a YAML error: the problem and where it is (line/column), without the source excerpt."""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{' '.join(str(problem).split())}{where}"


def load_yaml(text: str, where: str, error=CompassError):
    """``yaml.safe_load`` (tags such as ``!!python/object`` are refused, never executed)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise error(f"{where}: not valid YAML (safe loader): {yaml_problem(exc)}") from None


@contextmanager
def open_npz(path, error=CompassError, what="file"):
    """Yield a numpy ``NpzFile`` opened with ``allow_pickle=False``; close it (and the file) on every path.

    A missing file, a directory, a ``.npy`` saved under an ``.npz`` name, a corrupt or truncated zip:
    all raise ``error`` with the reason. Object arrays raise when read (pickle disabled), reported the same.
    """
    p = _existing_file(path, error, what)
    try:
        fh = open(p, "rb")
    except OSError as exc:
        raise error(f"{what} {str(p)!r} cannot be read: {exc.strerror}") from None
    with fh:
        try:
            z = np.load(fh, allow_pickle=False)
        except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
            raise error(f"{p.name}: not a readable .npz {what} ({_short(exc)})") from None
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise error(f"{p.name}: not an .npz archive (a single .npy array?); expected a {what}")
        with z:
            try:
                yield z
            except (zipfile.BadZipFile, EOFError, OSError) as exc:
                raise error(f"{p.name}: corrupt .npz {what} ({_short(exc)})") from None
            except ValueError as exc:
                if "pickle" in str(exc):
                    raise error(f"{p.name}: contains object arrays; refused (loading never unpickles)") from None
                raise error(f"{p.name}: unreadable array in the {what} ({_short(exc)})") from None


def _short(exc: Exception) -> str:
    s = " ".join(str(exc).split())
    return s if len(s) <= 160 else s[:157] + "..."
