"""PDS3 label encoding: attributes round-trip through pvl; no JSON, no escapes, no repeats."""

from __future__ import annotations

import math

import pvl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError
from fluxcal.products.label import (
    Symbol,
    attributes_object,
    check_unique_keys,
    decode_attributes,
    parse_label,
    render_label,
)

_text = st.text(max_size=20)  # any unicode: quotes, backslashes, blanks, newlines
_scalars = st.one_of(_text, st.integers(-(2**62), 2**62), st.booleans(), st.none(),
                     st.floats(allow_nan=False))
_values = st.recursive(
    _scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(_text, inner, max_size=3)),
    max_leaves=12,
)


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple)) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


@settings(max_examples=40, deadline=None)
@given(st.dictionaries(_text, _values, max_size=6))
def test_attributes_roundtrip_through_pvl(attrs: dict) -> None:
    """decode(pvl.loads(pvl.dumps(encode(a)))) == a for any JSON-like value, types kept."""
    module = pvl.PVLModule()
    module["DATASET_ATTRIBUTES"] = attributes_object(attrs)
    text = render_label(module)
    assert '\\"' not in text  # no backslash escapes (and no JSON strings)
    back = decode_attributes(pvl.loads(text)["DATASET_ATTRIBUTES"])  # pvl's default parser
    assert _same(attrs, back)
    assert text.endswith("END\r\n")


def test_nan_and_infinities_survive() -> None:
    module = pvl.PVLModule()
    module["A"] = attributes_object({"x": [math.nan, math.inf, -math.inf, 1e300]})
    back = decode_attributes(parse_label(render_label(module))["A"])["x"]
    assert math.isnan(back[0]) and back[1:] == [math.inf, -math.inf, 1e300]


def test_text_is_double_quoted_and_symbols_bare() -> None:
    module = pvl.PVLModule([("PDS_VERSION_ID", Symbol("PDS3")), ("DIGITS", "0123"),
                            ("NAME", "TIME.UTC"), ("SEQ", ["a", "b c"])])
    text = render_label(module)
    assert text.splitlines()[:4] == ['PDS_VERSION_ID = PDS3', 'DIGITS = "0123"',
                                     'NAME = "TIME.UTC"', 'SEQ = ("a", "b c")']
    back = parse_label(text)
    assert back["DIGITS"] == "0123" and back["SEQ"] == ["a", "b c"]


def test_repeated_keyword_is_refused() -> None:
    module = pvl.PVLModule([("A", 1), ("A", 2)])
    with pytest.raises(InputFormatError, match="A assigned twice"):
        render_label(module)
    inner = pvl.PVLModule([("T", pvl.PVLObject([("COLUMNS", 1), ("COLUMNS", 1)]))])
    with pytest.raises(InputFormatError, match="label/T"):
        check_unique_keys(inner)


def test_keyword_longer_than_30_characters_is_refused() -> None:
    with pytest.raises(InputFormatError, match="30 characters"):
        render_label(pvl.PVLModule([("K" * 31, 1)]))


def test_unparsable_label_is_an_input_format_error() -> None:
    with pytest.raises(InputFormatError, match="not a PDS3 label"):
        parse_label("A = (1, \r\nEND\r\n")


def test_fast_grammar_character_check_agrees_with_pvl():
    """The label encoder's set-lookup character check gives pvl's own verdict.

    Reference: ``pvl.grammar.PDSGrammar.char_allowed`` itself, over the first 12,288 code
    points (ASCII, latin-1 and beyond, where ODL allows nothing).
    """
    from pvl.grammar import PDSGrammar

    from fluxcal.products.label import _Grammar

    fast, ref = _Grammar(), PDSGrammar()
    assert all(fast.char_allowed(chr(o)) == ref.char_allowed(chr(o)) for o in range(0x3000))


def _fresh(module: pvl.PVLModule) -> str:
    """pvl's text with a new encoder: nothing remembered from earlier labels."""
    from fluxcal.products.label import _Encoder

    return pvl.dumps(module, encoder=_Encoder())


def _block(value: object) -> pvl.PVLModule:
    col = pvl.PVLObject([("NAME", "BX"), ("VALUE", value)])
    return pvl.PVLModule([("PDS_VERSION_ID", Symbol("PDS3")), ("COLUMN", col)])


def test_remembered_blocks_tell_apart_values_that_compare_equal() -> None:
    """0.0/-0.0, 1/True/1.0, a symbol and the same letters as text: one text each.

    Expected texts from a fresh pvl encoder (nothing remembered) for each label, after
    every other label was rendered once through the shared encoder.
    """
    values = [0.0, -0.0, 1, True, 1.0, Symbol("ABC"), "ABC", [1, 2], [1.0, 2.0]]
    for v in values:  # fill the shared encoder's memory with every variant first
        render_label(_block(v))
    texts = [render_label(_block(v)) for v in values]
    assert texts == [_fresh(_block(v)) for v in values]
    assert len(set(texts)) == len(values)


@settings(max_examples=30, deadline=None)
@given(st.dictionaries(_text, _values, max_size=4), st.dictionaries(_text, _values, max_size=4))
def test_label_text_does_not_depend_on_earlier_labels(a: dict, b: dict) -> None:
    """Rendering ``a``, ``b`` and ``a`` again gives pvl's fresh text of each every time."""
    mods = [pvl.PVLModule([("DATASET_ATTRIBUTES", attributes_object(x))]) for x in (a, b, a)]
    assert [render_label(m) for m in mods] == [_fresh(m) for m in mods]


def test_labels_render_quantities_without_importing_astropy() -> None:
    # pvl's own Quantity is still encoded in ODL's "value <unit>" form; astropy.units
    # (0.4 s to import) is left alone (docs/decisions/products.md, decision 51)
    import subprocess
    import sys

    pytest.importorskip("astropy")  # (without it, nothing could import it anyway)
    code = ("import sys, pvl\nfrom fluxcal.products.label import render_label\n"
            "m = pvl.PVLModule([('SAMPLING', pvl.collections.Quantity(0.05, 's'))])\n"
            "print(repr(render_label(m).splitlines()[0]), 'astropy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "'SAMPLING = 0.05 <s>' False"
