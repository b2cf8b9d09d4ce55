"""What a built firmware file may hold before the chip gets it: Intel HEX read within the flash, ELF checked.

A ``.hex`` or ``.elf`` handed to ``sim --firmware`` may be damaged, or made
to hurt: a HEX address record of 200 bytes, an extended address of
``FFFF`` that puts the next byte 4 GB up, an ELF built for x86, a section
table pointing past the end of the file. Neither the reader here nor
libsimavr's loader (which trusts the file: a section name it cannot find
is a null pointer, a symbol table with entries of size 0 a division by
zero, an ``.mmcu`` string without its end a buffer overrun) may meet such
a file, so each is checked here, in Python, before anything is allocated
for it or the harness is started: every record and section is within the
file, every address the chip is given within its flash (or EEPROM), the
ELF is a 32-bit little-endian AVR executable. A file that fails is one
line (``FirmwareRefused``, exit 1) naming the file and what is wrong.

``.mmcu`` (simavr's own section, which a firmware may carry to describe
its chip) is read as simavr reads it, and only the chip's description is
allowed in it (name, clock, voltages, fuses, signature, pull-ups): its
other tags make the emulator write trace files or a console on the host,
which a firmware someone sent you has no business doing. Standard library only.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from ...errors import HcrError

#: The most bytes a firmware file may have: an AVR ELF with debugging information is well under 1 MiB.
MAX_FILE_BYTES = 8 << 20
#: Flash and EEPROM of the chips ``pins.MCUS`` names (the datasheets').
FLASH_BYTES = {"atmega328p": 32 << 10, "atmega328": 32 << 10, "atmega168": 16 << 10}
EEPROM_BYTES = {"atmega328p": 1024, "atmega328": 1024, "atmega168": 512}
#: The most symbols an ELF may have: simavr sorts them by insertion, a cost that grows as their square.
MAX_SYMBOLS = 20_000

EM_AVR = 83
#: What a wrong ELF was built for, to say so (the common ones; any other is named by its number).
_MACHINES = {3: "x86", 62: "x86-64", 40: "ARM", 183: "AArch64", 243: "RISC-V", 8: "MIPS", 20: "PowerPC"}
_SHT_PROGBITS, _SHT_SYMTAB, _SHT_STRTAB, _SHT_NOBITS = 1, 2, 3, 8
#: The sections simavr's loader copies, by name: each must hold bytes from the file, and be there once.
_LOADED = (".text", ".data", ".eeprom", ".fuse", ".lock", ".mmcu")
#: ``.mmcu`` tags (``avr_mcu_section.h``): the end, the chip's name, then what may describe the chip.
_MMCU_END, _MMCU_NAME = 0, 1
_MMCU_DESCRIBES = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 17}  # up to the signature, and the port pull-ups
_MMCU_NAME_BYTES = 64  # elf_firmware_t.mmcu
_MMCU_LONG = {2, 3, 4, 5, 17}  # read as four bytes whatever the entry's length


class FirmwareRefused(HcrError):
    """A firmware file that is not one the chip can be given: damaged, or made for something else."""


def refused(name: str, why: str) -> FirmwareRefused:
    return FirmwareRefused(f"{name} is not a firmware the emulated chip can run: {why}")


# -- Intel HEX ----------------------------------------------------------------------------------

#: The longest HEX record line: ':', then count, address (2), type, 255 data bytes and the checksum, in hex.
_HEX_LINE = 1 + 2 * (5 + 255)


def hex_image(name: str, data: bytes, mcu: str) -> bytes:
    """The flash image an Intel HEX file describes (gaps 0xFF, as erased flash), every byte within ``mcu``'s flash.

    Each record is checked (its count, its checksum, its type 00-05, the two
    bytes of an address record) and each data record's place in the flash
    before a byte of the image is made for it.
    """
    flash = FLASH_BYTES[mcu]
    image = bytearray()
    base = 0
    for number, raw in enumerate(data.split(b"\n"), 1):
        line = raw.strip()
        if not line:
            continue
        count, address, kind, payload = _hex_record(name, number, line)
        if kind == 0:
            at = base + address
            if at + count > flash:
                raise refused(
                    name,
                    f"line {number} puts {count} byte{'s' * (count != 1)} at 0x{at:X}, outside the {flash >> 10} KiB flash of {mcu}",
                )
            image.extend(b"\xff" * max(0, at + count - len(image)))
            image[at : at + count] = payload
        elif kind == 1:
            break
        elif kind in (2, 4):
            base = int.from_bytes(payload, "big") << (4 if kind == 2 else 16)
    return bytes(image)


def _hex_record(name: str, number: int, line: bytes) -> tuple[int, int, int, bytes]:
    """One record's count, address, type and data; FirmwareRefused naming the line if it is none."""
    record = b""
    if line[:1] == b":" and len(line) <= _HEX_LINE:
        try:
            record = bytes.fromhex(line[1:].decode("ascii"))
        except ValueError:  # UnicodeDecodeError included
            record = b""
    if len(record) < 5 or len(record) != record[0] + 5 or sum(record) & 0xFF:
        raise refused(name, f"line {number} is not an Intel HEX record")
    count, address, kind, payload = record[0], int.from_bytes(record[1:3], "big"), record[3], record[4:-1]
    if kind > 5:
        raise refused(name, f"line {number} is a record of type {kind:02X}; Intel HEX has 00-05")
    size = {2: 2, 3: 4, 4: 2, 5: 4}.get(kind)
    if size is not None and count != size:
        raise refused(name, f"line {number}: a type {kind:02X} record holds {size} bytes, not {count}")
    return count, address, kind, payload


# -- ELF ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Section:
    name: bytes
    kind: int
    offset: int
    size: int
    link: int
    entsize: int


def check_elf(name: str, data: bytes, mcu: str) -> None:
    """Refuse (FirmwareRefused) an ELF that is not a whole AVR firmware fitting ``mcu``, as simavr reads it."""
    if data[:4] != b"\x7fELF" or len(data) < 52:
        raise refused(name, "it is no ELF file (or one cut short)")
    endian = "<" if data[5] == 1 else ">"
    (machine,) = struct.unpack_from(f"{endian}H", data, 18)
    if machine != EM_AVR:
        built = _MACHINES.get(machine, f"machine {machine}")
        raise refused(name, f"it is built for {built}, not AVR")
    if data[4] != 1 or data[5] != 1:
        raise refused(name, "an AVR ELF is 32-bit and little-endian; this one is not")
    kind, _, _, _, _, shoff, _, _, _, _, shentsize, shnum, shstrndx = struct.unpack_from(
        "<HHIIIIIHHHHHH", data, 16
    )
    if kind != 2:
        raise refused(name, f"it is not an executable (ELF type {kind})")
    sections = _sections(name, data, shoff, shentsize, shnum, shstrndx)
    _check_loaded(name, data, sections, mcu)


def _sections(
    name: str, data: bytes, shoff: int, shentsize: int, shnum: int, shstrndx: int
) -> list[_Section]:
    """The section table, every section's bytes and name within the file."""
    if shentsize != 40 or not 0 < shnum < 0xFF00 or shoff + shnum * 40 > len(data) or shstrndx >= shnum:
        raise refused(name, "its section table is damaged or outside the file")
    headers = [struct.unpack_from("<IIIIIIIIII", data, shoff + 40 * i) for i in range(shnum)]
    for number, (_, kind, _, _, offset, size, *_rest) in enumerate(headers):
        if kind != _SHT_NOBITS and offset + size > len(data):
            raise refused(name, f"its section {number} lies outside the file")
    _, names_kind, _, _, names_at, names_size, *_ = headers[shstrndx]
    if names_kind != _SHT_STRTAB:
        raise refused(name, "its section names are not a string table")
    names = data[names_at : names_at + names_size]
    return [
        _Section(_string(name, names, h[0], "section name"), h[1], h[4], h[5], h[6], h[9]) for h in headers
    ]


def _string(name: str, table: bytes, at: int, what: str) -> bytes:
    end = table.find(b"\0", at)
    if at >= len(table) or end < 0:
        raise refused(name, f"a {what} lies outside its string table")
    return table[at:end]


def _check_loaded(name: str, data: bytes, sections: list[_Section], mcu: str) -> None:
    """The sections simavr copies: each whole and once, and what they put in the chip within its memories."""
    named = _loaded(name, sections)
    text = named.get(".text")
    if text is None:
        raise refused(name, "it has no .text section (no code)")
    if ".lock" in named and ".fuse" not in named:
        raise refused(name, "it has a .lock section without .fuse (simavr reads the lock bits from .fuse)")
    base = _vectors(name, data, sections)
    code = text.size + (named[".data"].size if ".data" in named else 0)
    flash = FLASH_BYTES[mcu]
    if base + code > flash:
        raise refused(
            name,
            f"its code and data ({code} bytes at 0x{base:X}) do not fit the {flash >> 10} KiB flash of {mcu}",
        )
    eeprom = named.get(".eeprom")
    if eeprom is not None and eeprom.size > EEPROM_BYTES[mcu]:
        raise refused(name, f"its .eeprom ({eeprom.size} bytes) is larger than the EEPROM of {mcu}")
    mmcu = named.get(".mmcu")
    if mmcu is not None:
        _check_mmcu(name, data[mmcu.offset : mmcu.offset + mmcu.size])


def _loaded(name: str, sections: list[_Section]) -> dict[str, _Section]:
    """The sections simavr copies, by name: each there at most once, each holding bytes of the file."""
    named: dict[str, _Section] = {}
    for section in sections:
        label = section.name.decode("latin-1")
        if label not in _LOADED:
            continue
        if label in named:
            raise refused(name, f"it has two {label} sections")
        if section.kind != _SHT_PROGBITS:
            raise refused(name, f"its {label} section holds no bytes of the file")
        named[label] = section
    return named


def _vectors(name: str, data: bytes, sections: list[_Section]) -> int:
    """Where simavr loads the code: the last ``__vectors`` symbol's value (a bootloader's), else 0.

    Every symbol table is checked as simavr walks it: entries of 16 bytes,
    not too many, each name within its string table.
    """
    base = 0
    for section in sections:
        if section.kind != _SHT_SYMTAB:
            continue
        if section.entsize != 16 or section.size % 16 or section.size // 16 > MAX_SYMBOLS:
            raise refused(name, f"its symbol table is damaged or holds more than {MAX_SYMBOLS} symbols")
        if section.link >= len(sections) or sections[section.link].kind != _SHT_STRTAB:
            raise refused(name, "its symbol table names no string table")
        names_section = sections[section.link]
        names = data[names_section.offset : names_section.offset + names_section.size]
        for at in range(section.offset, section.offset + section.size, 16):
            st_name, value, _, info = struct.unpack_from("<IIIB", data, at)
            symbol = _string(name, names, st_name, "symbol name")
            if symbol == b"__vectors" and (info >> 4 == 1 or info & 0xF in (1, 2)):
                base = value
    return base


def _check_mmcu(name: str, section: bytes) -> None:
    """simavr's chip description, entry by entry as its loader reads it: each within the section, each allowed."""
    at = 0
    while at < len(section):
        if at + 2 > len(section):
            raise refused(name, "its .mmcu section ends inside an entry")
        tag, size = section[at], section[at + 1]
        body = section[at + 2 : at + 2 + size]
        if at + 2 + size > len(section) or (tag in _MMCU_LONG and size < 4):
            raise refused(name, "its .mmcu section ends inside an entry")
        if tag not in _MMCU_DESCRIBES:
            raise refused(name, f"its .mmcu section asks the emulator for more than the chip (tag {tag})")
        if tag == _MMCU_NAME and b"\0" not in body[:_MMCU_NAME_BYTES]:
            raise refused(name, f"its .mmcu chip name is longer than {_MMCU_NAME_BYTES - 1} bytes")
        at += 2 + size
