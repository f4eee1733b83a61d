"""Persistent directions: speed field, weighted FMM paths, bearings, clustering, tracking (Sec. IV-A a-b)."""
