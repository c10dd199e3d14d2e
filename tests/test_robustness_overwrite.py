"""``trajopt robustness --overwrite`` (issue #31 item 2): a folder holding a run with other
settings is refused without it (the folder untouched), and replaced with it: the old samples are
discarded, none of them reused."""
from __future__ import annotations

import json

from trajopt.cli import main

from .test_robustness import tiny_result


def test_overwrite_replaces_a_run_with_other_settings(tmp_path, capsys):
    result = tiny_result(tmp_path)
    out = tmp_path / "rob"
    base = ["robustness", str(result), "--samples", "2", "--cycles", "1", "--out", str(out)]
    assert main(base + ["--seed", "5"]) == 0
    old_lines = (out / "samples.jsonl").read_text()
    old_settings = (out / "settings.json").read_text()
    capsys.readouterr()
    assert main(base + ["--seed", "6"]) == 2
    err = capsys.readouterr().err
    assert "holds a robustness run with other settings" in err and "--overwrite" in err
    assert (out / "samples.jsonl").read_text() == old_lines and (out / "settings.json").read_text() == old_settings
    assert main(base + ["--seed", "6", "--overwrite"]) == 0
    assert "(0 done before)" in capsys.readouterr().out
    assert json.loads((out / "settings.json").read_text())["seed"] == 6
    assert json.loads((out / "report.json").read_text())["seed"] == 6
    new_lines = (out / "samples.jsonl").read_text().splitlines()
    assert len(new_lines) == 2 and "\n".join(new_lines) + "\n" != old_lines
