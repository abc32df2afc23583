"""Reading index.html back in tests."""

from __future__ import annotations

import re
from pathlib import Path


def linked_figures(folder: Path, page: str) -> list[str]:
    """The figures index.html shows, in order: linked by relative path, each an existing file
    under ``folder``, none embedded (each figure is stored once)."""
    assert "data:image/png;base64," not in page
    srcs = re.findall(r'<img src="([^"]+)"', page)
    assert all((folder / s).is_file() for s in srcs), srcs
    return srcs
