"""Messages about a YAML file a person edits (issue 27, the smaller ones): the line the user wrote, plain
words instead of Python type names, list entries by their names instead of 0-based positions, and lists
and mappings described instead of dumped."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.errors import ConfigError
from stiffness.files.yaml_schema import read_yaml

keys = st.lists(st.from_regex(r"[a-z][a-z_]{0,8}", fullmatch=True), min_size=2, max_size=12, unique=True)


@settings(max_examples=60, deadline=None)
@given(keys=keys, data=st.data())
def test_a_key_without_its_colon_is_reported_at_the_line_written(tmp_path_factory, keys, data):
    """PyYAML notices a missing colon when the next line starts; the message names the edited line."""
    nested = data.draw(st.booleans())
    lines = ["section:"] + [f"  {k}: {n}" for n, k in enumerate(keys)] if nested else \
        [f"{k}: {n}" for n, k in enumerate(keys)]
    first = 1 if nested else 0
    bad = data.draw(st.integers(first, len(lines) - 2))         # not the last: a next line shows it
    lines[bad] = lines[bad].replace(": ", " ", 1)
    path = tmp_path_factory.mktemp("yaml") / "c.yaml"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as err:
        read_yaml(path)
    message = str(err.value)
    assert message.startswith(f"{path}: line {bad + 1} ({lines[bad].strip()!r}) is not valid YAML"), message
    assert f"line {bad + 2}" in message.split("is not valid YAML")[1]      # and where PyYAML noticed it


@pytest.mark.parametrize("text, line, written", [
    ("filter:\n  cutoff_hz: 100\n  order 2\n  type: bessel\n", 3, "order 2"),
    ("gravity:\n  bias: [1, 2, 3\n  switch_ramp_s: 1\nlimits: {}\n", 2, "bias: [1, 2, 3"),
    ('model:\n  file: "abc\n  damping: 0.1\n', 2, 'file: "abc'),
    ("filter:\n  cutoff_hz: 100\n   order: 2\nlimits: {}\n", 3, "order: 2"),       # noticed where it is
])
def test_syntax_errors_name_the_line_and_quote_it(tmp_path, text, line, written):
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"c.yaml: line {line} \({written!r}\) is not valid YAML: ".replace("[", r"\[")):
        read_yaml(path)


@pytest.mark.parametrize("text, words", [
    ("", "the file is empty (or holds only comments)"),
    ("# only a comment\n", "the file is empty (or holds only comments)"),
    ("- a\n- b\n", "it holds a list of 2 entries"),
    ("42\n", "it holds a single value, 42"),
])
def test_a_file_that_is_no_mapping_is_described_in_words(tmp_path, text, words):
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        read_yaml(path)
    assert str(err.value) == f"{path}: expected a mapping of keys at the top level, but {words}"
    assert "NoneType" not in str(err.value)
