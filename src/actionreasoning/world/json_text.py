"""JSON text from outside (a model's answer, an outside agent's action), parsed so that every
way it can fail is one :class:`JSONTextError` with one line saying why.

``json.loads`` fails four ways: not JSON (``JSONDecodeError``), nested deeper than the
interpreter recurses (``RecursionError``), and a number too long to convert (a
``ValueError``: Python refuses integers of more than ``sys.get_int_max_str_digits()`` digits,
4300 by default, as text is turned into a number in time quadratic in its length).
"""

from __future__ import annotations

import json
import sys
from typing import Any


class JSONTextError(ValueError):
    """Text that is not JSON this package reads, and why, in one line."""


def parse_json(text: str) -> Any:
    """The value ``text`` holds, or :class:`JSONTextError`."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise JSONTextError(f"not valid JSON ({error.msg} at character {error.pos})") from None
    except RecursionError:
        raise JSONTextError("the JSON is nested too deeply") from None
    except ValueError:  # an integer too long to convert
        limit = sys.get_int_max_str_digits()
        raise JSONTextError(f"a number in the JSON has more than {limit} digits") from None
