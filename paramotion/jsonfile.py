"""Read the JSON input files (worlds, trunks, scenes) with one-line errors naming the file."""
from __future__ import annotations

import json
from pathlib import Path

from paramotion.errors import UserError


def load_json_object(path: str | Path, what: str) -> dict:
    """Parse ``path`` as a JSON object; any problem is a UserError '<what> <path>: ...'."""
    path = Path(path)
    try:
        text = path.read_text(encoding='utf-8')
    except FileNotFoundError:
        raise UserError(f'{what} {path}: cannot read: no such {what}') from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f'{what} {path}: cannot read ({exc})') from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f'{what} {path}: not valid JSON (line {exc.lineno}: {exc.msg})') \
            from None
    if not isinstance(data, dict):
        raise UserError(f'{what} {path}: top level must be a JSON object')
    return data
