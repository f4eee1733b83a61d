"""The model registries (``--reasoner``, ``--detector``, ``--segmenter``, ``--scorer``) and the one list of reference
agents: names and order as the command line shows them, what each backend needs, unknown names refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivenav.agents import reference_agent
from drivenav.errors import InputError
from drivenav.methods import REFERENCE_AGENTS
from drivenav.semantics.checked import CheckedGrounder, CheckedScorer
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.registry import (
    GROUNDER_BACKENDS,
    REASONER_BACKENDS,
    SCORER_BACKENDS,
    SEGMENTER_BACKENDS,
    Backend,
    ModelRegistry,
    check_models,
    make_grounder,
    make_reasoner,
    make_scorer,
    model_requirements,
    scorer_requirements,
)
from drivenav.types import SEMANTIC


def test_the_names_and_their_order_are_the_command_lines() -> None:
    assert REASONER_BACKENDS.names == ("embedded", "openai", "replay", "geometric", "oracle")
    assert GROUNDER_BACKENDS.names == ("embedded", "ground-truth", "sam3", "owlv2", "grounding-dino", "remote")
    assert SEGMENTER_BACKENDS.names == ("filled-box", "mobilesam")
    assert SCORER_BACKENDS.names == ("embedded", "blip2-itm", "siglip", "replay", "oracle")


def test_every_reference_agent_resolves_to_its_class() -> None:
    for name in REFERENCE_AGENTS:
        assert getattr(reference_agent(name), "name", None) == name


def test_the_stand_ins_need_ground_truth_labels() -> None:
    assert model_requirements(ModelSpec()) == frozenset({SEMANTIC})
    assert model_requirements(ModelSpec(reasoner="geometric", detector="ground-truth")) == frozenset({SEMANTIC})
    assert model_requirements(ModelSpec(reasoner="openai", detector="sam3")) == frozenset()
    assert GROUNDER_BACKENDS.reads_labels("no-such-detector") is False


def test_the_scorer_reads_labels_apart_from_the_model_requirements() -> None:
    """Only the methods that score frames add the scorer's needs; the other methods' stay."""
    assert scorer_requirements(ModelSpec()) == scorer_requirements(ModelSpec(scorer="embedded")) == {SEMANTIC}
    assert not any(scorer_requirements(ModelSpec(scorer=name)) for name in ("blip2-itm", "siglip", "replay", "x"))
    assert model_requirements(ModelSpec(reasoner="openai", detector="sam3", scorer="embedded")) == frozenset()


def test_backends_are_built_by_name() -> None:
    assert make_reasoner(ModelSpec(reasoner="geometric")).name == "geometric"
    grounder, scorer = make_grounder(ModelSpec(detector="ground-truth")), make_scorer(ModelSpec())
    assert isinstance(grounder, CheckedGrounder) and isinstance(scorer, CheckedScorer)  # their answers checked
    assert type(grounder.inner).__name__ == "GroundTruthGrounder"
    assert type(scorer.inner).__name__ == "EmbeddedScorer"


@pytest.mark.parametrize(
    ("spec", "option"),
    [
        (ModelSpec(reasoner="gpt"), "--reasoner"),
        (ModelSpec(detector="x"), "--detector"),
        (ModelSpec(detector="owlv2", segmenter="sam"), "--segmenter"),
        (ModelSpec(scorer="clip"), "--scorer"),
    ],
)
def test_an_unknown_name_is_one_line_naming_its_option(spec: ModelSpec, option: str) -> None:
    with pytest.raises(InputError, match=f"field '{option}': expected one of "):
        check_models(spec)


def test_every_cheap_check_runs_before_any_weights_load(tmp_path: Path) -> None:
    """A missing recording fails at once, though the scorer's checkpoint (also missing) is named first."""
    spec = ModelSpec(scorer="blip2-itm", scorer_model=str(tmp_path), reasoner="replay", vlm_replay=str(tmp_path / "r"))
    with pytest.raises(InputError, match="--vlm-replay"):
        check_models(spec)


CHECKED: list[str] = []
LENGTH: Backend[str] = Backend(lambda spec: f"length of {spec.vlm_model}", check=lambda spec: CHECKED.append("x"))
CLIP: Backend[str] = Backend(lambda spec: "clip", reads_labels=True)


def test_a_new_role_is_one_registry() -> None:
    """A later role (a scorer, say) reuses :class:`ModelRegistry`: its backends by ``module:attribute`` (what its
    entry points name), in order, each loaded when named; an unknown name is one line naming the role's option."""
    scorers: ModelRegistry[str] = ModelRegistry(
        "drivenav.scorers", {"length": f"{__name__}:LENGTH", "clip": f"{__name__}:CLIP"}, "--scorer"
    )
    assert scorers.names == ("length", "clip")
    assert scorers.get("length").build(ModelSpec(vlm_model="m")) == "length of m"
    scorers.get("length").check(ModelSpec())
    assert CHECKED == ["x"] and scorers.reads_labels("clip") and not scorers.reads_labels("nope")
    with pytest.raises(InputError, match="field '--scorer': expected one of length, clip, got 'nope'"):
        scorers.get("nope")


@pytest.mark.parametrize("detector", ["sam3", "embedded", "ground-truth"])
def test_a_box_segmenter_goes_with_a_box_detector_only(detector: str, tmp_path: Path) -> None:
    """SAM3 and the stand-ins make their own masks: --segmenter mobilesam with them is refused, not ignored; a
    served detector's segmenter is its server's business."""
    checkpoint = tmp_path / "mobile_sam.pt"
    checkpoint.write_bytes(b"")
    with pytest.raises(InputError) as caught:
        check_models(ModelSpec(detector=detector, segmenter="mobilesam", segmenter_model=str(checkpoint)))
    message = str(caught.value)
    assert "field '--segmenter': expected filled-box with --detector " in message
    assert "owlv2 and grounding-dino" in message and "\n" not in message
    check_models(ModelSpec(detector="remote", segmenter="mobilesam"), connect=False)


def test_mobilesam_needs_its_checkpoint_file_before_any_weights_load(tmp_path: Path) -> None:
    for given in ("", str(tmp_path), str(tmp_path / "missing.pt")):
        spec = ModelSpec(
            detector="owlv2", detector_model=str(tmp_path / "no"), segmenter="mobilesam", segmenter_model=given
        )
        with pytest.raises(InputError, match="field '--segmenter-model': expected a MobileSAM checkpoint file"):
            check_models(spec)


def test_a_shadow_url_is_checked_as_an_endpoint_naming_its_option() -> None:
    with pytest.raises(InputError, match="--detector-shadow-url"):
        check_models(ModelSpec(detector_shadow_url="not an endpoint"), connect=False)
    with pytest.raises(InputError, match="--detector-keys"):  # off loopback: CURVE keys
        check_models(ModelSpec(detector_shadow_url="tcp://10.0.0.1:5557"), connect=False)
