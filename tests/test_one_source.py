"""Facts said in two places are held together: a table row's code and its classes' ``CODE``.

Issue 25: each message class has a ``CODE`` and each table row a ``code``,
unchecked; a typo in either would frame requests under one code and name
their replies under another.
"""

from __future__ import annotations

import pytest

from hcrctl.protocol import commands as C
from hcrctl.protocol.messages import code_mismatch


@pytest.mark.parametrize("row", C.COMMANDS, ids=lambda row: row.name)
def test_every_row_of_the_table_has_the_code_its_classes_carry(row: C.Command) -> None:
    for cls in (row.request, row.reply):
        if cls is not None and cls is not C.ReadRequest:
            assert row.code == cls.CODE, f"{row.label}: {cls.__name__}.CODE is 0x{cls.CODE:02X}"
    assert code_mismatch(row.code, row.request, row.reply) is None


def test_a_class_whose_code_disagrees_with_its_row_is_named() -> None:
    said = code_mismatch(0x15, C.ReadRequest, C.Compass)
    assert said == "its reply class Compass has CODE 0x14, not the row's code 0x15"
    assert code_mismatch(0x22, C.Pid, None) == "its request class Pid has CODE 0x21, not the row's code 0x22"


def test_a_plugin_row_whose_classes_carry_another_code_is_refused() -> None:
    before = C.COMMANDS
    with pytest.raises(
        ValueError, match="heading: its reply class Compass has CODE 0x14, not the row's code 0x7E"
    ):
        C.register_command(C.Command(0x7E, "heading", "x", "read", C.ReadRequest, C.Compass, "x"))
    assert C.COMMANDS is before and 0x7E not in C.BY_CODE
