import doctest

import fluxcal.products


def test_module_docstring_example_runs() -> None:
    result = doctest.testmod(fluxcal.products, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
