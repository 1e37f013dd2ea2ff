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
    """Return the UTF-8 text of ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        File to read.
    error : type, default CompassError
        Exception class raised on failure (the caller's :class:`CompassError` subclass).
    what : str, default "file"
        What the file is, for the message (e.g. ``"scene file"``).

    Returns
    -------
    str
        The decoded text.

    Raises
    ------
    error
        The file is missing, a directory, unreadable, or not UTF-8 text (one-line message).
    """
    p = _existing_file(path, error, what)
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{what} {str(p)!r} is not UTF-8 text (byte {exc.start}); is it the right file?") from None
    except OSError as exc:
        raise error(f"{what} {str(p)!r} cannot be read: {exc.strerror}") from None


def yaml_problem(exc: yaml.YAMLError) -> str:
    """Return one line from a YAML error: the problem and where it is, without the source excerpt.

    Parameters
    ----------
    exc : yaml.YAMLError
        The parser's error.

    Returns
    -------
    str
        E.g. ``"found unexpected end of stream at line 3, column 1"`` (line and column 1-based,
        when the error has a mark).
    """
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{' '.join(str(problem).split())}{where}"


def load_yaml(text: str, where: str, error=CompassError):
    """Parse YAML text with ``yaml.safe_load``; tags such as ``!!python/object`` are refused.

    Parameters
    ----------
    text : str
        The YAML document.
    where : str
        Where it came from (a path or a parameter name), the prefix of the error message.
    error : type, default CompassError
        Exception class raised on failure.

    Returns
    -------
    object
        The parsed document (dict, list, scalar or None); nothing is executed.

    Raises
    ------
    error
        The text is not valid YAML for the safe loader (message with line and column).
    """
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise error(f"{where}: not valid YAML (safe loader): {yaml_problem(exc)}") from None


@contextmanager
def open_npz(path, error=CompassError, what="file"):
    """Open a ``.npz`` archive with ``allow_pickle=False``; close it on every path.

    A missing file, a directory, a ``.npy`` saved under an ``.npz`` name, a corrupt or truncated
    zip: all raise ``error`` with the reason. Object arrays raise when read (pickle disabled),
    reported the same way, as do corrupt members read inside the ``with`` body.

    Parameters
    ----------
    path : str or os.PathLike
        The archive.
    error : type, default CompassError
        Exception class raised on failure.
    what : str, default "file"
        What the archive is, for the message (e.g. ``"error map"``).

    Yields
    ------
    numpy.lib.npyio.NpzFile
        The open archive (arrays are read lazily by key).

    Raises
    ------
    error
        The file is missing, a directory, unreadable, not an ``.npz`` archive, corrupt, or holds
        object arrays.
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
