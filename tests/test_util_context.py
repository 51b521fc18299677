"""``set_within``: a context variable set for a ``with`` block, restored after it."""

from contextvars import ContextVar

import pytest

from spcopyro._util.context import set_within

_VAR: ContextVar[str] = ContextVar("test_set_within", default="before")


def test_set_within_sets_then_restores_even_after_an_exception() -> None:
    with set_within(_VAR, "inside"):
        assert _VAR.get() == "inside"
    assert _VAR.get() == "before"
    with pytest.raises(RuntimeError, match="boom"), set_within(_VAR, "inside"):
        assert _VAR.get() == "inside"
        raise RuntimeError("boom")
    assert _VAR.get() == "before"
