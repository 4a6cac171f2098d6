"""The paper's perception (issue 11 item 1): MLLM object list -> GroundingDINO boxes -> SAM masks.

The MLLM (prompt `frame_description`) lists the frame's objects (category, description) and
groups; GroundingDINO finds boxes for the categories (box threshold 0.40, text threshold
0.25, as in the official code), and a SAM-family model turns each box into a mask. Unlike
the official code, a category may have several instances in one frame: the k-th best box of
a category takes the k-th listed object of that category (extra boxes reuse the first one's
description).

Models load from a local folder (`save_pretrained` layout) only; nothing downloads at run
time. `transformers` and `torch` are imported when a model is loaded, not before.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, Field

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.llm import chat_structured
from glmap_tools.language.prompts import default_prompts
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS
from glmap_tools.perception.semantics import FrameSemantics, GroupObservation, ObjectObservation

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.language.llm import LLMClient
    from glmap_tools.language.prompts import PromptSet

# Imports inside functions stay there: torch, transformers load on first use; optional: PIL.

BOX_THRESHOLD = 0.40
TEXT_THRESHOLD = 0.25
FETCH_HINT = {
    "detector": "huggingface-cli download IDEA-Research/grounding-dino-tiny --local-dir {path}",
    "segmenter": "huggingface-cli download facebook/sam-vit-base --local-dir {path}",
}


def _load(kind: str, path: Path) -> tuple[Any, Any]:
    """(model, processor) of `kind` ("detector" or "segmenter") from a local folder."""
    if not (path / "config.json").is_file():
        raise InvalidInputError(
            f"{kind} model path {str(path)!r} does not hold a model (no config.json). Fetch "
            f"one once with `{FETCH_HINT[kind].format(path=path)}` and pass that folder; "
            "nothing is downloaded at run time."
        )
    import transformers as tf

    names = {
        "detector": ("GroundingDinoForObjectDetection", "GroundingDinoProcessor"),
        "segmenter": ("SamModel", "SamProcessor"),
    }[kind]
    try:
        model = getattr(tf, names[0]).from_pretrained(path, local_files_only=True)
        processor = getattr(tf, names[1]).from_pretrained(path, local_files_only=True)
    except (OSError, ValueError, KeyError) as exc:
        raise InvalidInputError(
            f"{kind} model path {str(path)!r} does not hold a loadable {names[0]} with its "
            f"{names[1]}: {exc}. Fetch one with `{FETCH_HINT[kind].format(path=path)}`."
        ) from exc
    model.eval()
    return model, processor


@dataclass(frozen=True)
class Detection:
    """One grounded box: the category phrase it answers, its score and pixel box."""

    category: str
    score: float
    box: tuple[float, float, float, float]  # x0, y0, x1, y1 pixels


def category_of(phrase: str, categories: Sequence[str]) -> str | None:
    """The category a detector phrase names (its words appear in it; longest first), or None.

    GroundingDINO phrases are the prompt tokens above the text threshold, e.g. "chair" or
    "office chair ." for the prompt "office chair. lamp.".
    """
    text = f" {' '.join(phrase.lower().replace('.', ' ').split())} "
    for category in sorted(categories, key=len, reverse=True):
        if f" {category} " in text:
            return category
    return None


@dataclass
class GroundedSegmenter:
    """GroundingDINO boxes for text categories, then SAM masks for the boxes.

    Args:
        detector_path: folder of a GroundingDINO model + processor.
        segmenter_path: folder of a SAM model + processor.
        box_threshold: minimum box score.
        text_threshold: minimum token score for a phrase to name a box.
    """

    detector_path: Path
    segmenter_path: Path
    box_threshold: float = BOX_THRESHOLD
    text_threshold: float = TEXT_THRESHOLD
    _models: tuple[Any, ...] = field(default=(), init=False, repr=False)

    def __post_init__(self) -> None:
        self.detector_path, self.segmenter_path = (
            Path(self.detector_path),
            Path(self.segmenter_path),
        )
        self._models = (
            *_load("detector", self.detector_path),
            *_load("segmenter", self.segmenter_path),
        )

    def detect(self, rgb: np.ndarray, categories: Sequence[str]) -> list[Detection]:
        """Boxes of `categories` in an [H, W, 3] uint8 image, best first."""
        import torch
        from PIL import Image

        detector, processor = self._models[0], self._models[1]
        words = list(dict.fromkeys(c.strip().lower() for c in categories if c.strip()))
        if not words:
            return []
        image = Image.fromarray(rgb)
        inputs = processor(images=image, text=". ".join(words) + ".", return_tensors="pt")
        with torch.no_grad():
            outputs = detector(**inputs)
        (result,) = processor.post_process_grounded_object_detection(
            outputs,
            inputs["input_ids"],
            threshold=self.box_threshold,
            text_threshold=self.text_threshold,
            target_sizes=[rgb.shape[:2]],
        )
        phrases = result["text_labels"] if "text_labels" in result else result["labels"]
        found = []
        for box, score, phrase in zip(result["boxes"], result["scores"], phrases, strict=True):
            category = category_of(str(phrase), words)
            if category is not None:
                x0, y0, x1, y1 = (float(v) for v in box)
                found.append(Detection(category, float(score), (x0, y0, x1, y1)))
        return sorted(found, key=lambda d: -d.score)

    def masks(self, rgb: np.ndarray, boxes: Sequence[tuple[float, ...]]) -> np.ndarray:
        """[K, H, W] bool SAM masks of pixel boxes (x0, y0, x1, y1) in an [H, W, 3] image."""
        import torch
        from PIL import Image

        sam, processor = self._models[2], self._models[3]
        if not boxes:
            return np.zeros((0, *rgb.shape[:2]), dtype=bool)
        inputs = processor(
            Image.fromarray(rgb), input_boxes=[[list(b) for b in boxes]], return_tensors="pt"
        )
        with torch.no_grad():
            outputs = sam(**inputs, multimask_output=False)
        (masks,) = processor.image_processor.post_process_masks(
            outputs.pred_masks, inputs["original_sizes"], inputs["reshaped_input_sizes"]
        )
        return masks[:, 0].numpy().astype(bool)


class ListedObject(BaseModel):
    """One object the MLLM lists."""

    id: int
    category: str = Field(min_length=1, max_length=200)
    description: str = Field(default="", max_length=MAX_DESCRIPTION_CHARS)


class ListedGroup(BaseModel):
    """One region the MLLM lists."""

    id: int
    description: str = Field(min_length=1, max_length=MAX_DESCRIPTION_CHARS)
    members: list[int] = Field(min_length=1)


class FrameDescription(BaseModel):
    """The MLLM's reply to `frame_description`."""

    objects: list[ListedObject] = Field(default_factory=list)
    groups: list[ListedGroup] = Field(default_factory=list)


def ground(
    listed: FrameDescription, detections: Sequence[Detection], masks: np.ndarray
) -> FrameSemantics:
    """Pair boxes with listed objects by category, rank by rank (see the module docstring).

    Args:
        listed: the MLLM's objects and groups.
        detections: boxes, best first.
        masks: [K, H, W] bool, one per detection.
    """
    by_category: dict[str, list[ListedObject]] = {}
    for obj in listed.objects:
        by_category.setdefault(obj.category.strip().lower(), []).append(obj)
    used: dict[str, int] = {}
    objects: list[ObjectObservation] = []
    next_extra = max([o.id for o in listed.objects], default=0) + 1
    for det, mask in zip(detections, masks, strict=True):
        pool = by_category.get(det.category.strip().lower())
        if not pool or not mask.any():
            continue
        k = used.get(det.category, 0)
        used[det.category] = k + 1
        if k < len(pool):
            source, local_id = pool[k], pool[k].id
        else:  # more boxes than listed objects: another instance, the first one's words
            source, local_id = pool[0], next_extra
            next_extra += 1
        objects.append(ObjectObservation(local_id, source.category, source.description, mask))
    present = {o.local_id for o in objects}
    groups = [
        GroupObservation(g.id, g.description, tuple(m for m in g.members if m in present))
        for g in listed.groups
        if any(m in present for m in g.members)
    ]
    return FrameSemantics(objects, groups)


@dataclass
class MLLMGroundedPerception:
    """The paper's perception backend: frame -> semantics (a `PerceptionBackend`)."""

    client: LLMClient
    segmenter: GroundedSegmenter
    prompts: PromptSet | None = None
    max_objects: int = 20

    def describe(self, frame: RGBDFrame) -> FrameDescription:
        """The MLLM's objects and groups of the frame (prompt `frame_description`)."""

        from PIL import Image

        prompt = (self.prompts or default_prompts()).get("frame_description")
        buffer = io.BytesIO()
        Image.fromarray(frame.rgb).save(buffer, format="PNG")
        message = {
            "role": "user",
            "content": prompt.format(max_objects=self.max_objects),
            "images": [buffer.getvalue()],
        }
        reply, _ = chat_structured(self.client, [message], FrameDescription, prompt=prompt)
        return reply

    def __call__(self, frame: RGBDFrame) -> FrameSemantics:
        listed = self.describe(frame)
        detections = self.segmenter.detect(frame.rgb, [o.category for o in listed.objects])
        masks = self.segmenter.masks(frame.rgb, [d.box for d in detections])
        semantics = ground(listed, detections, masks)
        semantics.validate(*frame.depth.shape)
        return semantics
