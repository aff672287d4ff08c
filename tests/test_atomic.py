"""atomic_path: all or nothing, and the file mode the umask gives (not a temp file's 0600)."""

import os
import stat

import pytest

from rfsdf.atomic import atomic_path
from rfsdf.errors import RfsdfError


@pytest.fixture
def umask():
    """Set the umask for one test and put the old one back."""
    old = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(old)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
def test_written_files_get_the_mode_the_umask_gives(tmp_path, umask, mask, mode):
    umask(mask)
    with atomic_path(tmp_path / "result.json") as tmp:
        tmp.write_text("{}")
    assert stat.S_IMODE((tmp_path / "result.json").stat().st_mode) == mode
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    assert stat.S_IMODE(plain.stat().st_mode) == mode  # the same as open() gives


def test_a_failed_write_leaves_nothing_behind(tmp_path):
    (tmp_path / "kept.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "kept.txt") as tmp:
        tmp.write_text("half")
        raise RuntimeError("crash")
    assert (tmp_path / "kept.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.txt"]


def test_an_unwritable_place_names_the_output_not_a_temporary_file(tmp_path):
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(RfsdfError, match=r"a-file/out.json: cannot write here"), \
            atomic_path(tmp_path / "a-file" / "out.json") as tmp:
        tmp.write_text("{}")
