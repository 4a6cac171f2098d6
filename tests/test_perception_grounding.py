"""The grounding path (GroundingDINO boxes, SAM masks) on tiny randomly initialised models.

The models are built from small configurations and saved to a temporary folder, so the real
loading and inference code runs; with random weights the boxes mean nothing, so the tests
hold the plumbing (shapes, thresholds, pairing, errors), not detection quality.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from glmap_tools import synthetic as sy
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.llm import OllamaClient
from glmap_tools.language.ollama_replay import ScriptedOllama, chat_reply
from glmap_tools.perception.grounding import (
    Detection,
    FrameDescription,
    GroundedSegmenter,
    MLLMGroundedPerception,
    category_of,
    ground,
)

WORDS = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", ".", "chair", "table", "lamp", "a"]


@pytest.fixture(scope="module")
def tiny_models(tmp_path_factory):
    torch = pytest.importorskip("torch")
    tf = pytest.importorskip("transformers")
    root = tmp_path_factory.mktemp("models")
    torch.manual_seed(0)
    backbone = tf.SwinConfig(
        embed_dim=16,
        depths=[1, 1, 1, 1],
        num_heads=[1, 1, 1, 1],
        window_size=4,
        out_features=["stage2", "stage3", "stage4"],
    )
    text = tf.BertConfig(
        vocab_size=len(WORDS),
        hidden_size=32,
        num_hidden_layers=1,
        num_attention_heads=2,
        intermediate_size=32,
        max_position_embeddings=64,
    )
    config = tf.GroundingDinoConfig(
        backbone_config=backbone,
        text_config=text,
        d_model=32,
        encoder_layers=1,
        decoder_layers=2,
        encoder_attention_heads=2,
        decoder_attention_heads=2,
        encoder_ffn_dim=32,
        decoder_ffn_dim=32,
        num_queries=12,
        num_feature_levels=3,
        encoder_n_points=2,
        decoder_n_points=2,
        max_text_len=32,
    )
    detector = root / "grounding-dino-tiny-random"
    tf.GroundingDinoForObjectDetection(config).save_pretrained(detector)
    tf.GroundingDinoProcessor(
        tf.GroundingDinoImageProcessor(size={"shortest_edge": 64, "longest_edge": 96}),
        tf.BertTokenizerFast(vocab={w: i for i, w in enumerate(WORDS)}),
    ).save_pretrained(detector)
    sam_config = tf.SamConfig(
        vision_config=tf.SamVisionConfig(
            hidden_size=16,
            output_channels=16,
            num_hidden_layers=1,
            num_attention_heads=1,
            image_size=64,
            patch_size=8,
            global_attn_indexes=[0],
            mlp_dim=16,
            num_pos_feats=8,
        ),
        prompt_encoder_config=tf.SamPromptEncoderConfig(
            hidden_size=16, image_size=64, patch_size=8, mask_input_channels=4
        ),
        mask_decoder_config=tf.SamMaskDecoderConfig(
            hidden_size=16,
            mlp_dim=16,
            num_hidden_layers=1,
            num_attention_heads=1,
            iou_head_hidden_dim=16,
        ),
    )
    segmenter = root / "sam-tiny-random"
    tf.SamModel(sam_config).save_pretrained(segmenter)
    tf.SamProcessor(
        tf.SamImageProcessor(size={"longest_edge": 64}, pad_size={"height": 64, "width": 64})
    ).save_pretrained(segmenter)
    return detector, segmenter


@pytest.fixture(scope="module")
def frame():
    boxes = sy.floor() + sy.chair(0.0, 0.5, object_id=1) + sy.table(1.3, 0.8, 2)
    return sy.view(boxes, (0.3, -2.0, 1.4), (0.3, 0.8, 0.4), 160, 120)[0]


def test_tiny_models_load_from_their_folders_and_give_boxes_and_masks(tiny_models, frame):
    grounded = GroundedSegmenter(*tiny_models, box_threshold=0.0, text_threshold=0.0)
    detections = grounded.detect(frame.rgb, ["chair", "table"])
    assert detections, "a zero threshold keeps every query"
    assert [d.score for d in detections] == sorted((d.score for d in detections), reverse=True)
    masks = grounded.masks(frame.rgb, [d.box for d in detections[:3]])
    assert masks.shape == (min(3, len(detections)), 120, 160) and masks.dtype == bool


def test_the_official_thresholds_are_the_defaults(tiny_models):
    grounded = GroundedSegmenter(*tiny_models)
    assert (grounded.box_threshold, grounded.text_threshold) == (0.40, 0.25)


def test_a_folder_without_a_model_says_how_to_fetch_one(tmp_path, tiny_models):
    with pytest.raises(InvalidInputError, match="huggingface-cli download IDEA-Research"):
        GroundedSegmenter(tmp_path, tiny_models[1])
    (tmp_path / "config.json").write_text("{}")
    with pytest.raises(InvalidInputError, match="does not hold a loadable SamModel"):
        GroundedSegmenter(tiny_models[0], tmp_path)


def test_a_detector_phrase_names_the_longest_category_it_contains():
    categories = ["chair", "office chair", "lamp"]
    assert category_of("office chair .", categories) == "office chair"
    assert category_of("chair", categories) == "chair"
    assert category_of("[UNK] [SEP]", categories) is None
    assert category_of("armchair", categories) is None


def test_several_boxes_of_one_category_become_several_instances():
    listed = FrameDescription.model_validate(
        {
            "objects": [
                {"id": 1, "category": "chair", "description": "a red chair"},
                {"id": 2, "category": "chair", "description": "a blue chair"},
                {"id": 3, "category": "table", "description": "a table"},
            ],
            "groups": [{"id": 1, "description": "dining", "members": [1, 3]}],
        }
    )
    masks = np.zeros((4, 10, 10), bool)
    for k in range(4):
        masks[k, k * 2 : k * 2 + 2] = True
    boxes = [
        Detection(c, s, (0, 0, 1, 1))
        for c, s in [("chair", 0.9), ("chair", 0.8), ("chair", 0.7), ("lamp", 0.6)]
    ]
    semantics = ground(listed, boxes, masks)
    assert [(o.local_id, o.description) for o in semantics.objects] == [
        (1, "a red chair"),
        (2, "a blue chair"),
        (4, "a red chair"),
    ]
    assert semantics.groups[0].members == (1,)


def test_the_mllm_lists_objects_and_the_tiny_models_ground_them(tiny_models, frame):
    def lists_a_chair(method, path, body):
        reply = {"objects": [{"id": 1, "category": "chair", "description": "a red chair"}]}
        return 200, chat_reply(body["model"], json.dumps(reply))

    grounded = GroundedSegmenter(*tiny_models, box_threshold=0.0, text_threshold=0.0)
    with ScriptedOllama(lists_a_chair) as model:
        client = OllamaClient("a-vision-model", host=model.host, retries=0, vision=True)
        semantics = MLLMGroundedPerception(client, grounded)(frame)
    assert semantics.objects, "a zero threshold grounds the listed chair"
    assert all(o.label == "chair" and o.mask.shape == (120, 160) for o in semantics.objects)


@pytest.mark.slow  # ~10 s: two Redwood frames through the build pipeline
def test_glmap_build_with_mllm_perception_runs_the_grounding_models(tiny_models, tmp_path, capsys):
    from glmap_tools.cli import main as glmap_main
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.map import GLMap

    def lists_a_chair(method, path, body):
        reply = {"objects": [{"id": 1, "category": "chair", "description": "a white chair"}]}
        return 200, chat_reply(body["model"], json.dumps(reply))

    out = tmp_path / "rw.glmap"
    base = ["build", "--out", str(out), "--quiet", "--embedder", "hashing", "--max-frames", "2"]
    base += ["--perception", "mllm"]
    assert glmap_main([*base, "--detector", str(tiny_models[0])]) != 0
    assert "--segmenter FOLDER" in capsys.readouterr().err
    with ScriptedOllama(lists_a_chair) as model:
        code = glmap_main(
            [*base, "--detector", str(tiny_models[0]), "--segmenter", str(tiny_models[1])]
            + ["--ollama-host", model.host, "--llm-model", "a-vision-model"]
        )
    assert code == 0
    glmap = GLMap.open(out, embedder=HashingEmbedder())
    try:
        assert len(glmap.trajectory) == 2
        assert {u.label for u in glmap.instances.values()} <= {"chair"}
    finally:
        glmap.close()
