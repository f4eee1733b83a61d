"""Depth + pose to obstacle / explored maps, frontiers, and the object map (paper Sec. IV-A a)."""
