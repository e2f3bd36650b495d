"""benchmarks/mjcf_survey.py: the page it writes names its own command so that a reader can paste it back into a
shell: the collections' names with spaces, the globs and the notes' parentheses quoted."""

import importlib.util
import re
import shlex
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "mjcf_survey.py"
spec = importlib.util.spec_from_file_location("mjcf_survey", SCRIPT)
survey = importlib.util.module_from_spec(spec)
sys.modules["mjcf_survey"] = survey
spec.loader.exec_module(survey)


def test_the_page_names_a_command_a_shell_reads_back(tmp_path):
    (tmp_path / "models").mkdir()
    out = tmp_path / "page.md"
    argv = ["--collection", f"a suite={tmp_path / 'models'}:*.xml", "--exclude", "scene*.xml",
            "--note", "a suite: its files (with their includes); nothing else", "--out", str(out)]
    assert survey.main(argv) == 0
    command = re.search(r"^- command: `(.*)`$", out.read_text(), re.MULTILINE).group(1)
    words = shlex.split(command)
    assert words[:2] == ["python", "benchmarks/mjcf_survey.py"]
    assert words[2:] == argv
