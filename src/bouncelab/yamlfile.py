"""Reading a YAML file the user wrote, with bad input reported as one error line."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from bouncelab.errors import BouncelabError


def read_yaml(path: str | Path, what: str) -> Any:
    """Parse the YAML file at ``path``; ``what`` names it in errors ("rig config file").

    Raises :class:`BouncelabError` naming the file when it is missing or not valid YAML.
    """
    path = Path(path)
    if not path.is_file():
        raise BouncelabError(path, f"{what} not found")
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise BouncelabError(path, f"YAML syntax error: {exc}") from None
