"""A hypothesis property run twice: on a small budget in the quick set, on its full budget in the slow set.

    @budgets(quick=300, full=3000)
    def test_numbers_are_float(budget):
        @settings(max_examples=budget)
        @given(s=decimals())
        def check(s):
            ...

        check()

`python -m pytest` runs the [300-examples] case, `python -m pytest -m slow` the [3000-examples] one; CI runs
both.  The property is defined inside the test so that each case gets its own budget with nothing but
hypothesis's public decorators; both cases share one entry in the example database (it is keyed on the
property's source), so an example that failed in the slow set is replayed first in the quick set.
"""
from __future__ import annotations

import pytest


def budgets(quick: int, full: int):
    """Parametrise a test over its number of examples: *quick* in the quick set, *full* marked slow."""
    assert quick <= full, (quick, full)
    return pytest.mark.parametrize("budget", [
        pytest.param(quick, id=f"{quick}-examples"),
        pytest.param(full, id=f"{full}-examples", marks=pytest.mark.slow),
    ])
