"""The packaged text-embedding table: it covers the embedded world's vocabulary, matches the model, and spares an
embedded-world run the encoder (the worker-memory goal)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.text_table import vocabulary_texts
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.semantics.embedding import TextEmbedder, default_embedder, packaged_model_dir, packaged_vectors
from drivenav.settings import load_settings

TABLE_TOLERANCE = 1e-6  # BLAS kernels differ between CPUs in the last bits; on the machine that wrote it: 0


def test_table_holds_every_vocabulary_text_and_the_models_vectors() -> None:
    table = packaged_vectors()
    assert sorted(table) == vocabulary_texts()
    model = TextEmbedder(packaged_model_dir())
    assert not model.encoder_loaded  # an explicit model folder starts with an empty cache
    for text, vector in table.items():
        assert vector.dtype == np.float32 and not vector.flags.writeable
        assert np.abs(model.embed([text])[0] - vector).max() <= TABLE_TOLERANCE, text
    assert model.encoder_loaded


def test_packaged_embedder_encodes_only_texts_outside_the_table() -> None:
    embedder = TextEmbedder()
    inside = vocabulary_texts()[:5]
    np.testing.assert_array_equal(embedder.embed(inside), np.stack([packaged_vectors()[t] for t in inside]))
    assert not embedder.encoder_loaded
    outside = "a lamp shaped like a lighthouse"
    assert outside not in packaged_vectors()
    vector = embedder.embed([outside])[0]
    assert embedder.encoder_loaded
    np.testing.assert_array_equal(vector, TextEmbedder(packaged_model_dir()).embed([outside])[0])


def test_a_drive_nav_run_on_the_embedded_world_never_loads_the_encoder(tmp_path: Path) -> None:
    default_embedder.cache_clear()
    episodes = generate_episodes(SceneLibrary("procedural:2", 7), 3, seed=7)
    settings = load_settings("drive-nav", options={"run.seed": 7, "sim.max_steps": 120})
    summary = evaluate(episodes, RunSpec(EmbeddedSpec("procedural:2", 7), settings), tmp_path, show_progress=False)
    assert summary.episodes == 3
    assert default_embedder.cache_info().currsize == 1  # the run used the shared embedder
    assert not default_embedder().encoder_loaded
