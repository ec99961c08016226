"""Reading the files users name (calibrations, randomization configs, recordings) with clear errors.

A missing file raises `MissingFileError`, a `FileNotFoundError` that is also a `ValueError`, whose
message is one line naming the file; a YAML file that cannot be parsed raises a `ValueError` naming
the file and where it is malformed. The command line prints either as one line and exits with 2.
"""

from __future__ import annotations

import errno
import os
from typing import Any


class MissingFileError(FileNotFoundError, ValueError):
    """A file the user named does not exist: a FileNotFoundError (what Python raises) and a
    ValueError (what qube_suite raises for every other bad argument)."""

    def __init__(self, path: str | os.PathLike, what: str):
        super().__init__(errno.ENOENT, f"no such {what} file", os.fspath(path))

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


def read_bytes(path: str | os.PathLike, what: str) -> bytes:
    """The content of the file at `path`; `what` names it in the error if it is missing
    (e.g. "recording" gives "x.jsonl: no such recording file")."""
    try:
        with open(path, "rb") as file:
            return file.read()
    except FileNotFoundError:
        raise MissingFileError(path, what) from None


def read_yaml(path: str | os.PathLike, what: str, loader: Any = None) -> Any:
    """The YAML document at `path`, read with `loader` (default: `yaml.SafeLoader`).

    Raises MissingFileError if there is no such file and ValueError naming the file if it is not
    valid YAML (or uses a tag safe loading refuses, such as !!python/object).
    """
    import yaml  # only needed for YAML files

    text = read_bytes(path, what)
    try:
        return yaml.load(text, Loader=loader or yaml.SafeLoader)  # noqa: S506  (a safe loader)
    except yaml.YAMLError as error:
        detail = " ".join(str(error).split())
        raise ValueError(f"{os.fspath(path)} is not a valid {what} YAML file: {detail}") from None
