"""Reading a recording back with the Rerun SDK, for assertions on what the dashboard wrote."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa
import rerun as rr


@dataclass
class Recording:
    """Per entity: its timelines, its rows (all chunks) and its component columns' values."""

    timelines: dict[str, set[str]] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)
    values: dict[str, dict[str, list[Any]]] = field(default_factory=dict)
    blueprints: int = 0

    def column(self, entity: str, component: str) -> list[Any]:
        """Every row's value of ``component`` (e.g. ``Scalars:scalars``) at ``entity``, or of a
        timeline (``sim_time``, ``wall_time``) in nanoseconds."""
        return self.values.get(entity, {}).get(component, [])

    def scalars(self, entity: str) -> list[float]:
        """The first value of each row of a Scalars entity."""
        return [row[0] for row in self.column(entity, "Scalars:scalars") if row]


def read_rrd(path: str | Path) -> Recording:
    """Load the data recording (and count the blueprints) of an .rrd file."""
    reader = rr.chunk.RrdReader(path)
    out = Recording(blueprints=len(reader.blueprints()))
    for chunk in reader.stream():
        ent = chunk.entity_path
        out.timelines.setdefault(ent, set()).update(chunk.timeline_names)
        out.rows[ent] = out.rows.get(ent, 0) + chunk.num_rows
        batch = chunk.to_record_batch()
        cols = out.values.setdefault(ent, {})
        for name in batch.schema.names:
            if ":" in name:
                cols.setdefault(name, []).extend(batch.column(name).to_pylist())
            elif name in chunk.timeline_names:  # as int64 nanoseconds
                cols.setdefault(name, []).extend(batch.column(name).cast(pa.int64()).to_pylist())
    return out


def view_origins(path: str | Path) -> dict[str, str]:
    """View name -> space origin, from the first blueprint stored in an .rrd file."""
    reader = rr.chunk.RrdReader(path)
    names: dict[str, str] = {}
    origins: dict[str, str] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for col, into in (("ViewBlueprint:display_name", names),
                          ("ViewBlueprint:space_origin", origins)):
            if col in batch.schema.names:
                into[chunk.entity_path] = batch.column(col).to_pylist()[-1][0]
    return {names.get(view, view): origin for view, origin in origins.items()}
