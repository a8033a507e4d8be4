"""Spliced pretty JSON is byte for byte what the standard library writes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agrisim.files.atomic import to_json
from agrisim.plugins.sinks.dataset import json_text


def _rows(n: int, rng: np.random.Generator) -> list[dict]:
    return [
        {
            "robot": f"r{i % 2 + 1}",
            "index": i,
            "reached": bool(rng.integers(2)),
            "ee_error_mm": float(rng.normal()) if i % 3 else None,
            "contacts": [f"a|b{j}" for j in range(i % 3)],
            "nested": {"q": rng.normal(size=i % 4).tolist(), "empty": {}, "none": []},
            "reason": 'no path \u00e9 "quoted"\nline',
        }
        for i in range(n)
    ]


@pytest.mark.parametrize("n", [0, 1, 5])
def test_arrays_and_objects_at_every_depth_match_json_dumps(n):
    rng = np.random.default_rng(n)
    rows = _rows(n, rng)
    frames = {f"r1_{i:03d}": {"T": rng.normal(size=(2, 2)).tolist(), "t": i * 0.1} for i in range(n)}
    plain = {
        "status": "running",
        "results": rows,
        "deep": {"inside": [1, {"frames": frames, "after": [rows, "x"]}]},
        "frames": frames,
        "last": np.float32(0.5),  # through `default`, outside the spliced parts
    }
    cache_rows, cache_frames = json_text.MemberCache(to_json), json_text.MemberCache(to_json)
    spliced = {
        "status": "running",
        "results": cache_rows.array(rows),
        "deep": {"inside": [1, {"frames": cache_frames.object(frames), "after": [cache_rows.array(rows), "x"]}]},
        "frames": cache_frames.object(frames),
        "last": np.float32(0.5),
    }
    assert json_text.dumps(spliced, default=to_json) == json.dumps(plain, indent=2, default=to_json)


def test_a_spliced_document_at_the_top_level():
    cache = json_text.MemberCache()
    assert json_text.dumps(cache.array([{"a": [1, 2]}, 3])) == json.dumps([{"a": [1, 2]}, 3], indent=2)
    assert json_text.dumps(cache.object({})) == "{}"


def test_members_are_encoded_once_and_again_when_they_change(monkeypatch):
    cache = json_text.MemberCache()
    rows = [{"i": 0, "contacts": []}, {"i": 1, "contacts": []}]
    calls = []
    real = json.dumps
    monkeypatch.setattr(json_text.json, "dumps", lambda obj, **kw: calls.append(obj) or real(obj, **kw))
    cache.array(rows)
    assert len(calls) == 2
    cache.array(rows)
    assert len(calls) == 2  # nothing new: all from the cache
    changed = [{"i": 0, "contacts": ["x|y"]}, rows[1], {"i": 2, "contacts": []}]
    text = json_text.Spliced(cache.array(changed).members, is_object=False).text(0)
    assert len(calls) == 4  # the changed row and the new one
    assert text == real(changed, indent=2)


def test_unserialisable_values_still_raise():
    with pytest.raises(TypeError, match="Path"):
        json_text.dumps({"p": Path("x"), "rows": json_text.MemberCache().array([1])})
