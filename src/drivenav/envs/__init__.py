"""Worlds behind one interface: the embedded simulator (default), later Habitat and a robot bridge."""
