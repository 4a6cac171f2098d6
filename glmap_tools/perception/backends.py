"""The model-backed perception backends, built from settings (one place for every CLI)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from glmap_tools.errors import InvalidInputError

# Imports inside functions stay there: language.embed load on first use: `glmap` imports every
# command module to build its parser.

MODEL_PERCEPTIONS = ("geometric+mllm", "mllm")


def model_perception(
    kind: str, settings: Any, detector: Path | None = None, segmenter: Path | None = None
) -> Any:
    """A frame -> FrameSemantics backend that uses a vision model (Ollama, or the MCP
    client's model when `settings.mllm` is "sampling").

    Args:
        kind: "geometric+mllm" (model-free segments named by the MLLM) or "mllm" (the
            paper's MLLM object list, GroundingDINO boxes and SAM masks).
        settings: `glmap_tools.language.backends.LLMSettings` (model, host, prompts).
        detector, segmenter: local GroundingDINO and SAM model folders ("mllm" only).

    Raises:
        InvalidInputError: an unknown kind, or "mllm" without its model folders.
    """
    if kind not in MODEL_PERCEPTIONS:
        raise InvalidInputError(f"perception {kind!r} is not one of {list(MODEL_PERCEPTIONS)}.")
    client = settings.vision_client()  # Ollama, or the MCP client's model (sampling)
    if kind == "mllm":
        from glmap_tools.perception.grounding import GroundedSegmenter, MLLMGroundedPerception

        if detector is None or segmenter is None:
            raise InvalidInputError(
                "--perception mllm needs --detector FOLDER (GroundingDINO) and --segmenter "
                "FOLDER (SAM): local model folders; nothing is downloaded at run time."
            )
        grounded = GroundedSegmenter(detector, segmenter)
        return MLLMGroundedPerception(client, grounded, prompts=settings.prompt_set())
    from glmap_tools.perception.mllm_naming import MLLMSegmentNamer

    return MLLMSegmentNamer(client, prompts=settings.prompt_set())
