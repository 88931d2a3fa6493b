"""The package's namespace holds its API and nothing else."""

from __future__ import annotations

import qfa_thermal as q


def test_the_namespace_is_the_api() -> None:
    """Every public name of the module is in ``__all__`` and every name in ``__all__``
    exists: no helper import (``np``, ``os``, ``Optional``) reads as API. Both ``dir`` and
    the module's own dictionary are checked, so a ``__dir__`` that hid names would not
    pass."""
    api = set(q.__all__)
    assert len(api) == len(q.__all__), "a name is listed twice in __all__"
    assert [n for n in q.__all__ if not hasattr(q, n)] == []
    assert {n for n in dir(q) if not n.startswith("_")} == api
    assert {n for n in vars(q) if not n.startswith("_")} == api
