"""rbody.files: nothing half written — a failed write leaves the old file, a report folder is all old or all new."""

from __future__ import annotations

import os

import numpy as np
import pytest

from rbody.files import UnwritableFolder, atomic_open, atomic_path, check_writable_folder, replaced_folder, write_atomic


def test_write_atomic_replaces_text_and_bytes(tmp_path):
    path = tmp_path / "a.json"
    write_atomic(path, "old")
    write_atomic(path, "new")
    assert path.read_text() == "new"
    write_atomic(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]  # no temporary left behind


def test_a_write_that_fails_half_way_leaves_the_old_file(tmp_path):
    path = tmp_path / "baseline.json"
    write_atomic(path, '{"metrics": {}}')
    with pytest.raises(RuntimeError):
        with atomic_open(path, "w") as handle:
            handle.write('{"metr')
            raise RuntimeError("disk full")
    assert path.read_text() == '{"metrics": {}}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["baseline.json"]


def test_atomic_path_keeps_the_suffix_for_writers_that_read_it(tmp_path):
    with atomic_path(tmp_path / "t.npz") as temporary:
        assert temporary.name.endswith(".npz") and temporary.parent == tmp_path
        np.savez(temporary, x=np.arange(3))
    assert np.load(tmp_path / "t.npz")["x"].tolist() == [0, 1, 2]
    umask = os.umask(0)
    os.umask(umask)
    assert os.stat(tmp_path / "t.npz").st_mode & 0o777 == 0o666 & ~umask  # as an ordinary open() makes it


def test_report_folder_is_all_old_or_all_new(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    (out / "report.md").write_text("old report")
    (out / "figure.png").write_text("old figure")
    (out / "bench").mkdir()
    (out / "bench" / "summary.md").write_text("another command's")
    with pytest.raises(RuntimeError):
        with replaced_folder(out) as staging:
            (staging / "report.md").write_text("new report")
            raise RuntimeError("interrupted before the figures")
    assert (out / "report.md").read_text() == "old report" and (out / "figure.png").read_text() == "old figure"
    with replaced_folder(out) as staging:
        (staging / "report.md").write_text("new report")
        (staging / "figure.png").write_text("new figure")
    assert (out / "report.md").read_text() == "new report" and (out / "figure.png").read_text() == "new figure"
    assert (out / "bench" / "summary.md").read_text() == "another command's"  # kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]              # nothing left beside it


def test_unwritable_folder_is_named(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(UnwritableFolder, match="cannot write into .*file/out"):
        check_writable_folder(blocker / "out")
