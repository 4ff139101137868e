"""Search strategies by name (`search.method` of a study).

Each is a generator `strategy(problem, config, rng) -> Generator[Batch, list[Outcome], Worst]`
(the contract in wcs/search/__init__.py).
"""
from __future__ import annotations

from .auto import auto
from .global_ import global_
from .local import local
from .sample import sample

STRATEGIES = {"sample": sample, "local": local, "global": global_, "auto": auto}
