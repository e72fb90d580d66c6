from __future__ import annotations

import io

from pipelines.progress import Progress


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_quiet_when_not_a_terminal() -> None:
    out = io.StringIO()
    with Progress("work", total=10, stream=out) as bar:
        for _ in range(10):
            bar.update()
    assert out.getvalue() == ""


def test_draws_on_a_terminal() -> None:
    out = _Tty()
    with Progress("work", total=4, stream=out) as bar:
        bar.update(4)
    text = out.getvalue()
    assert "work" in text and "100.0%" in text and text.endswith("\n")
