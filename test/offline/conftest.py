"""Fixtures of the offline tests."""

import sys

import pytest


@pytest.fixture
def no_pyplot(monkeypatch):
    """Make ``import matplotlib.pyplot`` fail: the offline plots must not use its state."""
    import matplotlib
    monkeypatch.setitem(sys.modules, 'matplotlib.pyplot', None)
    monkeypatch.delattr(matplotlib, 'pyplot', raising=False)
