"""The open-vocabulary object categories of the embedded world (HM3D-OVON-style homes and offices).

Each category carries its synonyms (the open-vocabulary task may name a target by any of them, Sec. III),
realistic box sizes, a mounting height, a placement style and per-room-type priors used by
:mod:`drivenav.envs.embedded.placement`. The data live in ``drivenav/data/vocabulary.json``; :func:`load_vocabulary`
validates a file of that schema and raises :class:`~drivenav.errors.InputError` on the first bad field.

Size convention (used by placement): ``sx`` is the extent along the wall the object stands against, ``sy``
its depth away from that wall, ``sz`` its height.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from drivenav.validation import Fields, read_json

Vec3 = tuple[float, float, float]


class PlacementStyle(str, Enum):
    """Where an object of a category goes in a room."""

    WALL = "wall"  # on the floor, back against a wall
    CORNER = "corner"  # on the floor, against a wall and slid into a corner
    CENTER = "center"  # on the floor, away from the walls
    MOUNTED = "mounted"  # on a wall at the category's elevation
    SURFACE = "surface"  # on top of a host object (one of ``hosts``)


@dataclass(frozen=True)
class CategorySpec:
    """One object category.

    ``priors`` maps room types to non-negative weights (missing types weigh 0); ``generic_prior`` is the
    weight in rooms of unknown type. ``elevation`` is the range of the box bottom above the floor (0 for
    furniture); ``max_per_room`` caps repeats in one room; ``hosts`` lists the categories a ``SURFACE``
    object may stand on.
    """

    name: str
    synonyms: tuple[str, ...]
    size_min: Vec3
    size_max: Vec3
    style: PlacementStyle
    priors: tuple[tuple[str, float], ...]
    generic_prior: float = 0.0
    elevation: tuple[float, float] = (0.0, 0.0)
    max_per_room: int = 2
    hosts: tuple[str, ...] = ()

    def prior(self, room_type: str | None) -> float:
        """Weight of this category in a room of ``room_type`` (``None``: unknown type, the generic prior)."""
        if room_type is None:
            return self.generic_prior
        return dict(self.priors).get(room_type, 0.0)

    def sample_size(self, rng: np.random.Generator) -> Vec3:
        """A size drawn uniformly per axis within ``[size_min, size_max]``."""
        sx, sy, sz = (float(rng.uniform(lo, hi)) for lo, hi in zip(self.size_min, self.size_max, strict=True))
        return sx, sy, sz

    def sample_elevation(self, rng: np.random.Generator) -> float:
        return float(rng.uniform(*self.elevation))


@dataclass(frozen=True, eq=False)
class Vocabulary:
    """All categories, the room types they refer to, per-room anchors and object densities.

    ``anchors`` name the categories placed first in every room of a type (a bedroom's bed); ``density`` is
    the expected number of further objects per m^2 of room floor, ``generic_density`` the same for space of
    unknown type.
    """

    room_types: tuple[str, ...]
    specs: tuple[CategorySpec, ...]
    anchors: Mapping[str, tuple[str, ...]]
    density: Mapping[str, float]
    generic_density: float

    @cached_property
    def _by_name(self) -> dict[str, CategorySpec]:
        return {spec.name: spec for spec in self.specs}

    @cached_property
    def _lookup(self) -> dict[str, str]:
        table: dict[str, str] = {}
        for spec in self.specs:
            for term in (spec.name, *spec.synonyms):
                table[normalize_term(term)] = spec.name
        return table

    def categories(self) -> list[str]:
        """Canonical category names, in file order."""
        return [spec.name for spec in self.specs]

    def spec(self, category: str) -> CategorySpec:
        """The spec of a canonical category name (``KeyError`` if unknown)."""
        return self._by_name[category]

    def canonical(self, name: str) -> str | None:
        """The canonical category for a name or synonym; case, spacing, '-' and '_' are ignored.

        A trailing plural ``s`` / ``es`` is dropped when the name itself is unknown. ``None`` if unresolved.
        """
        key = normalize_term(name)
        for candidate in (key, key[:-1] if key.endswith("s") else "", key[:-2] if key.endswith("es") else ""):
            if candidate and candidate in self._lookup:
                return self._lookup[candidate]
        return None

    def synonyms(self, category: str) -> tuple[str, ...]:
        return self.spec(category).synonyms

    def room_shares(self, category: str) -> dict[str, float]:
        """The category's room-type priors normalised to shares (empty for an unknown category or one without
        priors)."""
        spec = self._by_name.get(category)
        weights = {room: spec.prior(room) for room in self.room_types} if spec is not None else {}
        total = sum(weights.values())
        return {room: w / total for room, w in weights.items() if w > 0.0} if total > 0.0 else {}


SEEN_MIN_PRIOR = 3.0
"""A category with at least this weight in some room type counts as common (see :func:`vocabulary_split`)."""


@dataclass(frozen=True)
class VocabularySplit:
    """The categories split like HM3D-OVON's validation sets (Yokoyama et al., HM3D-OVON, arXiv 2409.14296):
    ``seen`` (val_seen names them, val_seen_synonyms names them by a synonym) and ``unseen`` (val_unseen: kept
    out of the seen set). Both in file order; together every category once."""

    seen: tuple[str, ...]
    unseen: tuple[str, ...]


def vocabulary_split(vocab: Vocabulary, seen_min_prior: float = SEEN_MIN_PRIOR) -> VocabularySplit:
    """Seen: the common categories, an anchor of some room type (placed in every room of that type) or weighted
    at least ``seen_min_prior`` in some room type, as HM3D-OVON's seen (training) categories are the frequent ones;
    unseen: every other category. Decided by the vocabulary file alone, so the same file gives the same split."""
    anchors = {name for names in vocab.anchors.values() for name in names}
    common = {spec.name for spec in vocab.specs if max((w for _, w in spec.priors), default=0.0) >= seen_min_prior}
    seen = tuple(name for name in vocab.categories() if name in anchors | common)
    return VocabularySplit(seen, tuple(name for name in vocab.categories() if name not in seen))


def normalize_term(name: str) -> str:
    """Lower case with spaces, hyphens and underscores removed: the key synonyms are matched on."""
    return "".join(name.lower().replace("-", " ").replace("_", " ").split())


def load_vocabulary(path: str | Path | None = None) -> Vocabulary:
    """Read and validate a vocabulary JSON file (default: the packaged ``data/vocabulary.json``)."""
    if path is None:
        text = resources.files("drivenav").joinpath("data/vocabulary.json").read_text(encoding="utf-8")
        return _parse(json.loads(text), "drivenav/data/vocabulary.json")
    return _parse(read_json(Path(path)), Path(path))


def _parse(raw: Any, source: str | Path) -> Vocabulary:
    fields = Fields(source)
    raw = fields.mapping(raw, "")
    room_types = tuple(fields.texts(raw.get("room_types"), "room_types"))
    specs = tuple(
        _parse_spec(entry, fields, f"categories[{k}]", room_types)
        for k, entry in enumerate(fields.sequence(raw.get("categories"), "categories"))
    )
    vocab = Vocabulary(
        room_types=room_types,
        specs=specs,
        anchors={
            room: tuple(fields.texts(names, f"anchors.{room}"))
            for room, names in fields.mapping(raw.get("anchors"), "anchors").items()
        },
        density={
            room: fields.number(value, f"density.{room}", minimum=0.0)
            for room, value in fields.mapping(raw.get("density"), "density").items()
        },
        generic_density=fields.number(raw.get("generic_density"), "generic_density", minimum=0.0),
    )
    _check_references(vocab, fields)
    return vocab


def _parse_spec(entry: Any, fields: Fields, where: str, room_types: tuple[str, ...]) -> CategorySpec:
    item = fields.mapping(entry, where)
    size_min = _size(fields, item.get("size_min"), f"{where}.size_min")
    size_max = _size(fields, item.get("size_max"), f"{where}.size_max")
    if any(lo > hi for lo, hi in zip(size_min, size_max, strict=True)):
        raise fields.error(f"{where}.size_max", "size_max >= size_min per axis", size_max)
    style_name = fields.choice(item.get("style"), f"{where}.style", [s.value for s in PlacementStyle])
    priors = fields.mapping(item.get("priors", {}), f"{where}.priors")
    for room in priors:
        fields.choice(room, f"{where}.priors.{room}", room_types)
    low, high = fields.numbers(item.get("elevation", [0.0, 0.0]), f"{where}.elevation", 2, "[low, high] metres")
    if not 0.0 <= low <= high:
        raise fields.error(f"{where}.elevation", "[low, high] with 0 <= low <= high", [low, high])
    max_per_room = fields.integer(item.get("max_per_room", 2), f"{where}.max_per_room", minimum=1)
    return CategorySpec(
        name=fields.text(item.get("name"), f"{where}.name"),
        synonyms=tuple(fields.texts(item.get("synonyms", []), f"{where}.synonyms")),
        size_min=size_min,
        size_max=size_max,
        style=PlacementStyle(style_name),
        priors=tuple((room, fields.number(w, f"{where}.priors.{room}", minimum=0.0)) for room, w in priors.items()),
        generic_prior=fields.number(item.get("generic", 0.0), f"{where}.generic", minimum=0.0),
        elevation=(low, high),
        max_per_room=max_per_room,
        hosts=tuple(fields.texts(item.get("hosts", []), f"{where}.hosts")),
    )


def _check_references(vocab: Vocabulary, fields: Fields) -> None:
    """Names and synonyms map to one category each; anchors, densities and hosts name known things."""
    names = vocab.categories()
    owner: dict[str, str] = {}
    for k, spec in enumerate(vocab.specs):
        where = f"categories[{k}]"
        terms = [("name", spec.name), *((f"synonyms[{j}]", term) for j, term in enumerate(spec.synonyms))]
        for part, term in terms:
            key = normalize_term(term)
            if not key:
                raise fields.error(f"{where}.{part}", "a term with letters or digits", term)
            if owner.setdefault(key, spec.name) != spec.name:
                raise fields.error(f"{where}.{part}", f"a term no other category has ('{owner[key]}' has it)", term)
        if spec.style is PlacementStyle.SURFACE and not spec.hosts:
            raise fields.error(f"{where}.hosts", "at least one host for a surface object", [])
        for j, host in enumerate(spec.hosts):
            fields.choice(host, f"{where}.hosts[{j}]", names, "a category name of this file")
    for room, anchors in vocab.anchors.items():
        fields.choice(room, f"anchors.{room}", vocab.room_types)
        for j, anchor in enumerate(anchors):
            fields.choice(anchor, f"anchors.{room}[{j}]", names, "a category name of this file")
    for room in vocab.density:
        fields.choice(room, f"density.{room}", vocab.room_types)


def _size(fields: Fields, value: Any, where: str) -> Vec3:
    """Three positive numbers (metres)."""
    sx, sy, sz = fields.numbers(value, where, 3, "three positive numbers (metres)", positive=True)
    return sx, sy, sz


VOCABULARY: Vocabulary = load_vocabulary()


def categories() -> list[str]:
    """Canonical names of the packaged vocabulary."""
    return VOCABULARY.categories()


def canonical_category(name: str) -> str | None:
    """Resolve a category name or synonym against the packaged vocabulary (see :meth:`Vocabulary.canonical`)."""
    return VOCABULARY.canonical(name)


def synonyms(category: str) -> tuple[str, ...]:
    """Synonyms of a canonical category of the packaged vocabulary."""
    return VOCABULARY.synonyms(category)


def category_spec(category: str) -> CategorySpec:
    """The spec of a canonical category of the packaged vocabulary."""
    return VOCABULARY.spec(category)
