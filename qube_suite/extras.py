"""Optional dependencies: imported on use, with one line saying how to install them."""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

MEDIA_HINT = "pip install 'qube_suite[media]'"
"""How to get matplotlib and imageio-ffmpeg (plots and videos)."""


def available(module: str) -> bool:
    """Whether `module` can be imported."""
    return importlib.util.find_spec(module) is not None


def require(module: str, purpose: str, extra: str = "media") -> ModuleType:
    """Import `module`, or raise ImportError saying that `purpose` needs the `extra` (default: media)."""
    if not available(module):
        raise ImportError(f"{purpose} needs {module.split('.')[0]}: pip install 'qube_suite[{extra}]'")
    return importlib.import_module(module)
