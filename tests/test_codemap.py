"""The code map in docs/development.md names every package and every module, and nothing else.

A map that leaves modules out stops being read; one that names modules gone
misleads. The map is the fenced block under "How the code is organised": a
line that starts with ``PACKAGE/`` (``hcrctl/`` for the root, ``sim/firmware/``
for a subpackage) begins that package's entry, and every word outside
parentheses in the entry is a module of it (``__init__`` may be named when it
holds more than a docstring; it is never required).
"""

from __future__ import annotations

import pytest
from helpers_codemap import MAP, ON_DISK, entries


def test_every_package_has_an_entry_and_every_entry_a_package() -> None:
    assert sorted(set(ON_DISK) - set(MAP)) == [], "packages the code map does not name"
    assert sorted(set(MAP) - set(ON_DISK)) == [], "the code map names packages that do not exist"


@pytest.mark.parametrize("package", sorted(ON_DISK))
def test_the_code_map_names_each_module_of_the_package(package: str) -> None:
    missing = sorted(ON_DISK[package] - MAP.get(package, set()) - {"__init__"})
    assert not missing, (
        f"hcrctl/{package}: modules the code map in docs/development.md does not name: {missing}"
    )


@pytest.mark.parametrize("package", sorted(MAP))
def test_the_code_map_names_no_module_that_does_not_exist(package: str) -> None:
    gone = sorted(MAP[package] - ON_DISK.get(package, set()))
    assert not gone, f"hcrctl/{package}: the code map names modules that do not exist: {gone}"


def test_the_check_reads_names_outside_parentheses_only() -> None:
    """A module named only inside a description does not count, so a missing one cannot hide there."""
    block = "hcrctl/  errors (the HcrError family (all of it))\n  sim/  serve, hub (not world)\n"
    assert entries(block) == {"": {"errors"}, "sim": {"serve", "hub"}}
