"""Relighting a catalogue: photos x looks into a folder (``relight batch``), resumable by content,
on worker processes here or Ray actors on a cluster (docs/batch.md)."""
