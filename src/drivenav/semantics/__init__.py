"""Reasoner and grounding protocols, their backends, prompt enrichment and verification (Sec. IV-B, IV-C)."""
