import io
import time

from click.testing import CliRunner

from rfsdf import progress
from rfsdf.cli import main
from rfsdf.progress import progress_bar, set_quiet


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_log_gets_no_redraws_from_a_short_stage():
    log = io.StringIO()
    for _ in progress_bar(range(5000), desc="short", stream=log):
        pass
    assert log.getvalue() == ""


def test_a_log_gets_plain_throttled_lines_from_a_long_stage(monkeypatch):
    monkeypatch.setattr(progress, "LOG_INTERVAL_S", 0.05)
    log = io.StringIO()
    for _ in progress_bar(range(30), desc="long", stream=log, leave=True):
        time.sleep(0.01)  # 0.3 s in all: about 6 intervals
    text = log.getvalue()
    lines = text.splitlines()
    assert "\r" not in text and 2 <= len(lines) <= 12, text
    assert all(line.startswith("long:") for line in lines)
    assert "30/30" in lines[-1]


def test_a_terminal_gets_a_bar_that_redraws_unless_quiet():
    screen = _Terminal()
    for _ in progress_bar(range(3), desc="bar", stream=screen):
        pass
    assert "\r" in screen.getvalue() and "bar" in screen.getvalue()
    set_quiet(True)
    try:
        silent = _Terminal()
        for _ in progress_bar(range(3), desc="bar", stream=silent):
            pass
        assert silent.getvalue() == ""
    finally:
        set_quiet(False)


def test_quiet_is_a_global_option(tmp_path):
    runner = CliRunner()
    assert runner.invoke(main, ["--quiet", "scene", "show", "sphere", "--out", str(tmp_path / "s.png")]).exit_code == 0
    assert progress._quiet
    assert runner.invoke(main, ["scene", "show", "sphere", "--out", str(tmp_path / "s.png")]).exit_code == 0
    assert not progress._quiet
