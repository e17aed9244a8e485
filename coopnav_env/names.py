"""'Did you mean' for mistyped names (scenarios, policies, task sets, tasks).

raise ValueError(f"unknown policy {name!r}{did_you_mean(name, valid)} valid: ...")
# unknown policy 'fim_c'; did you mean 'fim_a'? valid: ...
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = ["did_you_mean"]


def did_you_mean(name: object, valid: Iterable[object]) -> str:
    """``"; did you mean 'x'?"`` with the closest of ``valid`` to ``name``
    (``difflib.get_close_matches``), or ``";"`` when none is close: the house style
    ``unknown policy 'fim_c'; did you mean 'fim_a'? valid: ...``."""
    close = difflib.get_close_matches(str(name), [str(v) for v in valid], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ";"
