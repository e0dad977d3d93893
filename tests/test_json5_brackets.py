"""json5_brackets.unbalanced: where a JSON5 text's structure breaks, read past strings and comments."""

import pytest

from radarodom.json5_brackets import unbalanced


@pytest.mark.parametrize("text", [
    "", "{}", "{ mode: 'peer', listen: { endpoints: ['tcp/127.0.0.1:0'] } }",
    "{ a: '}', b: \"]\", c: 'it\\'s', d: \"a \\\"q\\\" }\" }",  # brackets and quotes inside strings
    "{ // a comment's ' and {\n a: 1 /* ] and \" */ }",  # ... and inside comments
    "{ a: 'one \\\ntwo' }",  # a string continued on the next line by a backslash
])
def test_a_balanced_text_has_nothing_to_say(text):
    assert unbalanced(text) is None


@pytest.mark.parametrize("text, where", [
    ("{ a: [1, 2 }", "1:12: this '}' closes the '[' opened at 1:6, which needs ']'"),
    ("{\n  a: { b: 1 }\n", "1:1: this '{' is never closed (the text ends first)"),
    ("{\n  a: { b: [1,\n", "2:11: this '[' is never closed (the text ends first)"),
    ("{ a: 1 }\n}", "2:1: this '}' closes nothing"),
    ("{\n  a: 'one\n}", "2:6: this string has no closing ' on its line"),
    ('{ a: "x\\" }', '1:6: this string has no closing " on its line'),  # the escaped quote does not close
    ("{ /* a: 1 }", "1:3: this /* comment is never closed by */"),
])
def test_the_first_break_is_named_by_line_and_column(text, where):
    assert unbalanced(text) == where
