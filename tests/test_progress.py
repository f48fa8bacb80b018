"""Progress bars: on or off per call, the items unchanged either way."""

from __future__ import annotations

from rapomdp.progress import progress_bar, track


def test_track_yields_every_item_with_or_without_a_bar() -> None:
    items = [3, 1, 2]
    assert list(track(items, "off", enabled=False)) == items
    assert list(track(iter(items), "on, no length", enabled=True)) == items
    assert list(track(items, "on", enabled=True)) == items


def test_a_disabled_bar_is_invisible() -> None:
    assert progress_bar(False).disable
    assert not progress_bar(True).disable
    assert progress_bar(True, status=True).columns[3].text_format == "{task.fields[status]}"


def test_the_count_names_what_it_counts() -> None:
    from rapomdp.progress import CountColumn

    bar = progress_bar(False)
    counted = bar.add_task("render", total=385, unit="models")
    bar.advance(counted, 12)
    plain = bar.add_task("plain", total=None)
    assert str(CountColumn().render(bar.tasks[counted])) == "12/385 models"
    assert str(CountColumn().render(bar.tasks[plain])) == "0/?"
    assert isinstance(progress_bar(True).columns[2], CountColumn)
