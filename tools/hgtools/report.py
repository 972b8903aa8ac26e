"""Reports under bench/results/ that a bench writes and a person annotates: the bench rewrites
the part above the notes marker and keeps what was written below it, so that rerunning a bench
refreshes its tables without dropping the prose that explains them."""
from __future__ import annotations

from pathlib import Path

NOTES_MARKER = "<!-- notes: written by hand; the bench that writes this file keeps everything below this line -->"


def write_report(path: str | Path, generated: str) -> str:
    """Writes `generated` to path, followed by the marker and the notes the file had below it
    (none: just the marker, for the notes to come). Returns the notes kept."""
    path = Path(path)
    notes = ""
    if path.exists():
        old = path.read_text()
        if NOTES_MARKER in old:
            notes = old.split(NOTES_MARKER, 1)[1].lstrip("\n")
    path.write_text(generated.rstrip("\n") + "\n\n" + NOTES_MARKER + "\n" + ("\n" + notes if notes else ""))
    return notes
