"""The page every study writes: the answer first, then a table of contents whose links resolve, tables in plain
numbers that link their CSV, and no ``nan`` or exponent anywhere a reader looks."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from rlcompare.formatting import NO_DATA, distinct_numbers, number
from rlcompare.report.page import Section, render_report, shown, write_table


@pytest.mark.parametrize(("value", "text"), [
    (2490.0, "2,490"), (-176.4, "-176"), (8.6789, "8.68"), (12.345, "12.3"), (0.00123, "0.00123"),
    (1e-7, "0.0000001"), (3.0, "3"), (1234567.8, "1,234,568"), (float("nan"), NO_DATA), (-0.5, "-0.5"),
    (8.7, "8.7"), (5.3e-05, "0.000053"), (1440.4, "1,440"), (float("inf"), "∞"), (None, NO_DATA),
])
def test_numbers_are_written_as_a_reader_writes_them(value: float, text: str) -> None:
    """One formatter for tables, notes and sentences: about three significant digits, never an exponent."""
    assert number(value) == text


def test_two_numbers_get_the_digits_that_tell_them_apart() -> None:
    assert distinct_numbers(5.31e-05, 6.9e-05) == ("0.000053", "0.000069")
    assert distinct_numbers(0.12341, 0.12349) == ("0.1234", "0.1235")
    assert distinct_numbers(2.0, 2.0) == ("2", "2")


TABLE = pd.DataFrame({"configuration": ["sarsa-constant", "q_learning-constant"], "episodes": [2490.0, np.nan],
                      "p": [1e-7, 0.15], "solved": [True, False], "estimate": ["8.68 [1.89, 14.52]", None]})


def test_a_table_shows_plain_numbers_and_says_where_it_has_none() -> None:
    frame = shown(TABLE)
    assert frame["episodes"].tolist() == ["2,490", NO_DATA]
    assert frame["p"].tolist() == ["0.0000001", "0.15"]
    assert frame["solved"].tolist() == [True, False]
    assert frame["estimate"].tolist() == ["8.68 [1.89, 14.52]", NO_DATA]


def test_markdown_shows_what_the_page_shows_and_the_csv_keeps_every_digit(tmp_path) -> None:
    assert write_table(TABLE, tmp_path / "tables", "verdicts") == "tables/verdicts.csv"
    markdown = (tmp_path / "tables" / "verdicts.md").read_text()
    assert "nan" not in markdown
    assert NO_DATA in markdown
    assert "2,490" in markdown
    assert pd.read_csv(tmp_path / "tables" / "verdicts.csv")["p"].iloc[0] == 1e-7


def test_the_page_opens_with_the_answer_then_contents_whose_links_resolve() -> None:
    sections = [Section("The answer", ["SARSA collects 8.7 more reward per episode."]),
                Section("Table I: time to converge", tables=[("Table I", TABLE, "tables/table_i.csv")]),
                Section("Videos", ["none"])]
    page = render_report("A study", sections, [])
    assert page.index("The answer") < page.index('<nav class="contents">') < page.index("Table I: time")
    links = re.findall(r'href="#([^"]+)"', page)
    assert links == ["table-i-time-to-converge", "videos"]
    for target in links:
        assert f'id="{target}"' in page
    assert '<a class="files" href="tables/table_i.csv">CSV</a>' in page
    cells = " ".join(re.findall(r"<td[^>]*>([^<]*)</td>", page))
    assert "nan" not in cells
    assert not re.search(r"\de[+-]\d", cells)
    assert NO_DATA in cells


def test_a_page_of_one_section_has_no_contents() -> None:
    assert "<nav" not in render_report("A study", [Section("The answer", ["yes"])], [])
