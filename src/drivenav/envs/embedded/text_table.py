"""The packaged text-embedding table: all-MiniLM-L6-v2 vectors of every text the embedded world can embed.

The embedded reasoner and detector compare normalised phrases of the vocabulary (category names and synonyms: the
goals, the instance labels and the prompts made from them). Their vectors ship in
:data:`drivenav.semantics.embedding.PACKAGED_TABLE`, so an embedded-world worker never loads the 90 MB model
(the worker-memory goal); a text outside the table still gets an encoder pass. After a change to the
vocabulary, rewrite the table with ``python -m drivenav.envs.embedded.text_table`` (a test checks that it covers the
vocabulary and matches the model).
"""

from __future__ import annotations

import sys

from drivenav.envs.vocabulary import VOCABULARY
from drivenav.semantics.embedded import normalize_phrase
from drivenav.semantics.embedding import TextEmbedder, packaged_model_dir, packaged_table, write_table


def vocabulary_texts() -> list[str]:
    """Every category name and synonym of the vocabulary, normalised as the embedded models embed them, sorted."""
    names = {name for category in VOCABULARY.categories() for name in (category, *VOCABULARY.synonyms(category))}
    return sorted({normalize_phrase(name) for name in names})


def main() -> int:
    """Rewrite the packaged table from the packaged model (every vector from an encoder pass of its own)."""
    path = packaged_table()
    texts = vocabulary_texts()
    write_table(path, texts, TextEmbedder(packaged_model_dir()))
    print(f"{path}: {len(texts)} texts")
    return 0


if __name__ == "__main__":
    sys.exit(main())
