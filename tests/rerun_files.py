"""Reading back the .rrd files the commands write, with the rerun SDK's own reader."""

from pathlib import Path

from rerun.chunk import RrdReader


def entities(path: Path) -> dict[str, dict]:
    """Entity path -> {"components": set of "Archetype:field", "rows": rows logged (static ones included)}."""
    found: dict[str, dict] = {}
    for chunk in RrdReader(str(path)).stream().to_chunks():
        entry = found.setdefault(chunk.entity_path, {"components": set(), "rows": 0})
        batch = chunk.to_record_batch()
        entry["components"].update(f.name for f in batch.schema if ":" in f.name)
        entry["rows"] += batch.num_rows
    return found
