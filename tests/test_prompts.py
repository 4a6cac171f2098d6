"""Prompt files: one source for the repository folder and the installed package."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.language.prompts import PromptSet, package_prompts_dir

ROOT = Path(__file__).resolve().parents[1]
# Each prompt's placeholders, as the code that fills it passes them.
FIELDS = {
    "frame_description": {"max_objects"},
    "unit_value_instance": {"goal", "units"},
    "unit_value_region": {"goal", "units"},
    "text_merge": {"kind", "max_words", "descriptions"},
    "sqa_situation": {"situation", "kind_plural", "question", "units"},
    "sqa_answer": {"situation", "views", "context", "question"},
    "tool_agent_system": {"task", "max_turns"},
    "segment_naming": {"segments"},
}


def test_the_package_prompts_are_the_repository_prompts_folder():
    assert package_prompts_dir().resolve() == (ROOT / "prompts").resolve()
    assert sorted(PromptSet().names()) == sorted(p.stem for p in (ROOT / "prompts").glob("*.txt"))


def test_every_prompt_has_the_placeholders_its_caller_fills():
    prompts = PromptSet()
    assert set(prompts.names()) == set(FIELDS)
    for name, fields in FIELDS.items():
        prompt = prompts.get(name)
        assert prompt.fields == fields, name
        text = prompt.format(**{f: f"<{f}>" for f in fields})
        assert "{" not in text.replace("{{", "") or '"' in text  # JSON examples keep braces
        assert len(prompt.sha256) == 64 and prompt.ref == f"{name}@{prompt.sha256[:12]}"


def test_a_built_wheel_carries_the_same_prompt_bytes(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            str(ROOT),
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("*.whl")
    with zipfile.ZipFile(wheel) as z:
        for path in (ROOT / "prompts").glob("*.txt"):
            assert z.read(f"glmap_tools/prompts/{path.name}") == path.read_bytes()


def test_an_override_folder_replaces_prompts_by_name_and_changes_their_hash(tmp_path):
    default = PromptSet().get("text_merge")
    (tmp_path / "text_merge.txt").write_text(
        "Merge these {kind} notes into {max_words} words:\n{descriptions}\n"
    )
    prompts = PromptSet(tmp_path)
    custom = prompts.get("text_merge")
    assert custom.source == str(tmp_path / "text_merge.txt")
    assert custom.sha256 != default.sha256
    assert (
        prompts.get("unit_value_instance").sha256 == PromptSet().get("unit_value_instance").sha256
    )
    assert set(prompts.refs()) == {"text_merge", "unit_value_instance"}


def test_a_prompt_out_of_step_with_its_caller_names_the_placeholders(tmp_path):
    (tmp_path / "text_merge.txt").write_text("Merge {descriptions} for {room}.")
    with pytest.raises(
        InvalidInputError, match=r"without a value \['room'\].*\['kind', 'max_words'\]"
    ):
        PromptSet(tmp_path).get("text_merge").format(kind="object", max_words=300, descriptions="x")


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ('Reply as {"id": <id>} for {goal}', '{"id": <id>}'),  # JSON with single braces
        ("Score {goal} }", "Single '}' encountered"),
        ("Score { {goal}", "unexpected '{'"),
        ("Score {goal.upper} {units}", "{goal.upper}"),
        ("Score {goal[0]} {units}", "{goal[0]}"),
        ("Score {goal!r} {units}", "{goal!r}"),
        ("Score {goal:>40} {units}", "{goal:>40}"),
        ("Score {} {units}", "placeholder {}"),
    ],
)
def test_a_prompt_file_str_format_cannot_fill_is_refused_when_its_folder_is_given(
    tmp_path, text, said
):
    from glmap_tools.language.backends import LLMSettings

    path = tmp_path / "unit_value_instance.txt"
    path.write_text(text)
    fix = r"placeholders are a name in braces, e\.g\. \{goal\}; write literal braces as \{\{"
    for make in (lambda: PromptSet(tmp_path), lambda: LLMSettings(prompts=tmp_path)):
        with pytest.raises(InvalidInputError, match=rf"prompt file {path}.*{fix}") as caught:
            make()
        assert said in str(caught.value)
    path.write_text("Score {{literal}} and {goal} over {units}.")  # doubled braces are text
    (tmp_path / "notes.txt").write_text("not a prompt: {a.b}")  # no prompt's name: not read
    assert PromptSet(tmp_path).get("unit_value_instance").fields == {"goal", "units"}


def test_an_unknown_prompt_suggests_the_closest_name():
    with pytest.raises(UnknownIdError, match="Did you mean 'text_merge'"):
        PromptSet().get("text_merg")


def test_an_override_that_is_not_a_folder_is_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="is not a folder"):
        PromptSet(tmp_path / "missing")


def test_backends_default_offline_and_select_the_llm_parts_by_name(tmp_path):
    from glmap_tools.language.backends import LLMSettings, make_scorer, make_text_merger
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.language.llm_merger import LLMTextMerger
    from glmap_tools.language.llm_scorer import LLMScorer
    from glmap_tools.language.text_merger import ExtractiveTextMerger
    from glmap_tools.nav import EmbeddingScorer

    embedder = HashingEmbedder()
    offline = LLMSettings()
    assert not offline.uses_llm
    assert isinstance(make_text_merger(offline, embedder), ExtractiveTextMerger)
    assert isinstance(make_scorer(offline, embedder), EmbeddingScorer)
    (tmp_path / "text_merge.txt").write_text("{kind} {max_words} {descriptions}")
    llm = LLMSettings("llm", "llm", model="gemma3:4b", host="http://127.0.0.1:9", prompts=tmp_path)
    merger, scorer = make_text_merger(llm, embedder), make_scorer(llm, embedder)
    assert isinstance(merger, LLMTextMerger) and isinstance(scorer, LLMScorer)
    assert merger.client.model == "gemma3:4b" and merger.client.host == "http://127.0.0.1:9"
    assert merger.prompts.get("text_merge").source == str(tmp_path / "text_merge.txt")
    with pytest.raises(InvalidInputError, match="Did you mean 'llm'"):
        LLMSettings(scorer="lm")


def test_the_server_gives_every_map_the_text_merger_its_settings_ask_for(tmp_path):
    from glmap_tools.app.state import SessionRegistry
    from glmap_tools.language.backends import LLMSettings
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.language.llm_merger import LLMTextMerger
    from glmap_tools.language.text_merger import ExtractiveTextMerger
    from glmap_tools.server import ServerConfig
    from glmap_tools.server.cli import build_parser, config_from_args

    args = build_parser().parse_args(["--text-merger", "llm", "--llm-model", "qwen3:4b"])
    config = config_from_args(args)
    assert config.llm == LLMSettings(text_merger="llm", model="qwen3:4b")
    for llm, kind in ((config.llm, LLMTextMerger), (LLMSettings(), ExtractiveTextMerger)):
        registry = SessionRegistry(
            ServerConfig(maps_dir=tmp_path / "maps", embedder="hashing", llm=llm),
            HashingEmbedder(),
        )
        assert isinstance(registry._scratch().glmap.text_merger, kind)


def test_glmap_mcp_picks_the_perception_of_unannotated_frames():
    from glmap_tools.perception.mllm_naming import MLLMSegmentNamer
    from glmap_tools.server.cli import build_parser, perception_from_args

    parse = build_parser().parse_args
    assert perception_from_args(parse([])) is None  # pending: the agent names segments
    namer = perception_from_args(parse(["--perception", "geometric+mllm", "--llm-model", "x:1b"]))
    assert isinstance(namer, MLLMSegmentNamer) and namer.client.vision
    with pytest.raises(InvalidInputError, match="needs --detector FOLDER"):
        perception_from_args(parse(["--perception", "mllm"]))
