from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.products.label import parse_label, render_label

_keys = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,12}", fullmatch=True).filter(
    lambda k: k not in ("END", "OBJECT", "END_OBJECT"))
_scalars = st.one_of(st.text(max_size=20), st.integers(-(2**62), 2**62),
                     st.floats(allow_nan=False, allow_infinity=False))
_values = st.one_of(_scalars, st.lists(_scalars, min_size=1, max_size=4),
                    st.dictionaries(st.text(max_size=5), st.integers(), max_size=3))


@settings(max_examples=60, deadline=None)
@given(st.dictionaries(_keys, _values, max_size=6))
def test_label_roundtrip_law(attrs: dict) -> None:
    """parse(render(statements)) == statements for strings, numbers, sequences and dicts."""
    from fluxcal.products.attrs import decode_value

    text = render_label([("OBJECT", ("A", list(attrs.items())))])
    (key, (name, body)), = parse_label(text)
    assert (key, name) == ("OBJECT", "A")
    back = {k: decode_value(v) for k, v in body}
    assert back == attrs
    assert text.endswith("END\r\n")
