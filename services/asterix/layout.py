"""Fast record splitting from libasterix's category specifications.

libasterix parses a record into objects item by item (≈1,000–2,000 CAT048 records/s
in pure Python). The reader only needs a few items, and most of a record is skipped,
so this module compiles a category's UAP, *as libasterix defines it*, into a table
of byte-length rules and splits records with plain integer arithmetic:

* fixed items (Element/Group): ``bit_size / 8`` bytes;
* Extended items: FX-chained groups of known sizes (an FX bit set in the last group
  is an error, as in libasterix);
* Repetitive items: a repetition count (``rep_bytes``) times a fixed element, or
  FX-chained fixed elements;
* Explicit items (RE/SP): a length byte that counts itself (0 is an error);
* Compound items: an FX-chained FSPEC (at most ``cv_fspec_max_bytes``) and the
  present subitems, recursively.

:func:`split_record` returns the end offset and the byte span of each present item,
or a short error text. It applies the strict-parsing checks of libasterix (FSPEC too
long or unterminated, FSPEC bit of a spare or undefined slot, data too short); a
record using Random Field Sequencing is refused so the caller falls back to
libasterix. The equivalence is checked by a differential test against libasterix on
random and real records.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from asterix.base import (
    Compound,
    Element,
    Explicit,
    Extended,
    Group,
    Repetitive,
    RuleVariationContextFree,
    UapItem,
    UapItemRFS,
)

# Rule tuples: ("fixed", n) | ("ext", ((group_bytes, ends_with_fx), ...)) | ("rep", count_bytes, n)
# | ("repfx", n) | ("explicit",) | ("compound", max_fspec, (rule | None, ...))
Rule = tuple


def _variation(nsp: Any) -> Any:
    rule = nsp.cv_rule
    if isinstance(rule, type) and issubclass(rule, RuleVariationContextFree):
        return rule.cv_variation
    return rule.cv_default_variation  # libasterix parses dependent items with the default


def _bits(var: Any) -> int:
    if issubclass(var, (Element, Group)):
        return var.cv_bit_size
    raise TypeError(f"{var} has no fixed size")


def compile_rule(var: Any) -> Rule:
    """Byte-length rule of one libasterix variation class."""
    if issubclass(var, (Element, Group)):
        if var.cv_bit_size % 8:
            raise TypeError(f"{var}: {var.cv_bit_size} bits is not a whole number of bytes")
        return ("fixed", var.cv_bit_size // 8)
    if issubclass(var, Extended):
        groups = []
        for group in var.cv_items_list:
            bits = sum(1 if x is None else x[1] for x in group)
            if bits % 8:
                raise TypeError(f"{var}: group of {bits} bits")
            groups.append((bits // 8, bool(group) and group[-1] is None))
        return ("ext", tuple(groups))
    if issubclass(var, Repetitive):
        elem = _bits(var.cv_variation)
        if var.cv_rep_bytes is None:
            if (elem + 1) % 8:
                raise TypeError(f"{var}: FX element of {elem} bits")
            return ("repfx", (elem + 1) // 8)
        if elem % 8:
            raise TypeError(f"{var}: element of {elem} bits")
        return ("rep", var.cv_rep_bytes, elem // 8)
    if issubclass(var, Explicit):
        return ("explicit",)
    if issubclass(var, Compound):
        subs = tuple(None if s is None else compile_rule(_variation(s)) for s in var.cv_items_list)
        return ("compound", var.cv_fspec_max_bytes, subs)
    raise TypeError(f"unsupported variation {var}")


@dataclass(frozen=True)
class RecordLayout:
    """A category's UAP as (name, rule) per FSPEC slot; name None = spare, "RFS" = RFS."""

    fspec_max_bytes: int
    slots: tuple[tuple[str | None, Rule | None], ...]


def compile_layout(spec: Any) -> RecordLayout:
    """Compile ``spec`` (e.g. ``asterix.generated.Cat_048_1_32``) to a RecordLayout."""
    record = spec.cv_uap.cv_record
    slots = []
    for item in record.cv_items_list:
        if issubclass(item, UapItem):
            nsp = item.cv_non_spare
            slots.append((nsp.cv_name, compile_rule(_variation(nsp))))
        elif issubclass(item, UapItemRFS):
            slots.append(("RFS", None))
        else:
            slots.append((None, None))
    return RecordLayout(record.cv_fspec_max_bytes, tuple(slots))


def _fspec(data: bytes, pos: int, max_bytes: int) -> tuple[int, str | None]:
    """End of the FSPEC starting at ``pos``, or an error."""
    end = pos
    n = len(data)
    while True:
        if end >= n:
            return end, "insufficient data, fspec"
        byte = data[end]
        end += 1
        if not byte & 1:
            break
    if end - pos > max_bytes:
        return end, "fspec too big"
    return end, None


def _skip(data: bytes, pos: int, rule: Rule) -> int:
    """End of the item at ``pos`` under ``rule``; -1 if the data are too short/invalid."""
    kind = rule[0]
    n = len(data)
    if kind == "fixed":
        end = pos + rule[1]
        return end if end <= n else -1
    if kind == "ext":
        groups = rule[1]
        for k, (size, has_fx) in enumerate(groups):
            pos += size
            if pos > n:
                return -1
            if not has_fx or not data[pos - 1] & 1:
                return pos
            if k == len(groups) - 1:
                return -1  # last FX bit set
        return -1
    if kind == "rep":
        if pos + rule[1] > n:
            return -1
        count = int.from_bytes(data[pos : pos + rule[1]], "big")
        end = pos + rule[1] + count * rule[2]
        return end if end <= n else -1
    if kind == "repfx":
        size = rule[1]
        while True:
            pos += size
            if pos > n:
                return -1
            if not data[pos - 1] & 1:
                return pos
    if kind == "explicit":
        if pos >= n or data[pos] == 0:
            return -1
        end = pos + data[pos]
        return end if end <= n else -1
    if kind == "compound":
        end, err = _fspec(data, pos, rule[1])
        if err:
            return -1
        subs = rule[2]
        slot = 0
        p = end
        for i in range(pos, end):
            byte = data[i]
            for bit in range(7):
                if byte & (0x80 >> bit):
                    if slot >= len(subs) or subs[slot] is None:
                        return -1
                    p = _skip(data, p, subs[slot])
                    if p < 0:
                        return -1
                slot += 1
        return p
    return -1


def split_record(
    data: bytes, pos: int, layout: RecordLayout
) -> tuple[int, dict[str, tuple[int, int]]] | str:
    """Split the record at ``pos``: ``(end, {item name: (start, end)})`` or an error.

    An error text means "not handled here" (malformed, or RFS): re-parse with
    libasterix for the authoritative result and message."""
    end, err = _fspec(data, pos, layout.fspec_max_bytes)
    if err:
        return err
    items: dict[str, tuple[int, int]] = {}
    slots = layout.slots
    slot = 0
    p = end
    for i in range(pos, end):
        byte = data[i]
        for bit in range(7):
            if byte & (0x80 >> bit):
                if slot >= len(slots):
                    return "fspec bit beyond the UAP"
                name, rule = slots[slot]
                if name is None:
                    return "fx bit set for spare item"
                if rule is None:
                    return "random field sequencing"
                q = _skip(data, p, rule)
                if q < 0:
                    return f"insufficient or invalid data, item {name}"
                items[name] = (p, q)
                p = q
            slot += 1
    return p, items


def split_item_bytes(
    data: bytes, pos: int, layout: RecordLayout
) -> tuple[dict[str, bytes], int] | None:
    """The record at ``pos`` as ``({item name: item bytes}, end)`` — the form the
    item-byte decoders read (:func:`.records.item_bytes` gives it for a libasterix
    record) — or ``None`` when :func:`split_record` does not handle it (re-parse with
    libasterix for the authoritative error)."""
    split = split_record(data, pos, layout)
    if isinstance(split, str):
        return None
    end, spans = split
    return {k: data[s:e] for k, (s, e) in spans.items()}, end


def build_fspec(layout: RecordLayout, present: list[str]) -> bytes:
    """The FSPEC announcing the ``present`` items of ``layout`` (FX bits set on all but
    the last byte), as libasterix writes it."""
    index = {name: i for i, (name, _) in enumerate(layout.slots) if name}
    slots = [index[name] for name in present]
    if not slots:
        return b"\x00"
    n = max(slots) // 7 + 1
    out = bytearray(n)
    for i in slots:
        out[i // 7] |= 0x80 >> (i % 7)
    for k in range(n - 1):
        out[k] |= 1
    return bytes(out)


__all__ = ["RecordLayout", "build_fspec", "compile_layout", "compile_rule", "split_record"]
