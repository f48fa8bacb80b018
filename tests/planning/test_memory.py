"""The memory cap's figures and its error."""

from __future__ import annotations

import pickle

import pytest

from rapomdp.planning.memory import MemoryCapError, cap_bytes, check_memory, format_bytes


def test_sizes_are_printed_in_decimal_units():
    assert [format_bytes(x) for x in (512, 37e6, 11.9e9, 3.2e11)] == [
        "512 B", "37 MB", "11.9 GB", "320 GB"]


def test_the_cap_refuses_with_a_named_error_that_crosses_processes():
    check_memory("small", 1e9, 4.0)
    with pytest.raises(MemoryCapError, match="^big needs about 12.8 GB, over the memory cap "
                                             "of 4 GB") as info:
        check_memory("big", 12.8e9, 4.0)
    again = pickle.loads(pickle.dumps(info.value))  # as a worker process re-raises it
    assert (again.what, again.needed_bytes, again.cap_bytes) == ("big", 12.8e9, 4e9)
    assert str(again) == str(info.value)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="memory_gb must be a positive finite number"):
            cap_bytes(bad)
