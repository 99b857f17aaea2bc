"""Sea state -> (Hs, Tp) from the documented table ``bb2_sim/data/sea_state_table.yaml`` (source in the file)."""
from __future__ import annotations

from .data import sea_data
from .errors import SeaInputError


def sea_state_hs_tp(sea_state: int) -> tuple[float, float]:
    """(Hs m, Tp s) of an integer sea state in the table (2..8)."""
    table = sea_data("sea_state_table.yaml")["sea_states"]
    try:
        ss = int(sea_state)
    except (TypeError, ValueError) as exc:
        raise SeaInputError(f"sea state must be an integer, got {sea_state!r}") from exc
    if ss != sea_state or ss not in table:
        raise SeaInputError(f"sea state {sea_state!r} is not in the table (integers {min(table)}..{max(table)})")
    row = table[ss]
    return float(row["hs"]), float(row["tp"])
