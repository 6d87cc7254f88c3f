"""CDR byte layouts taken from rosbags: encode many messages of one shape with NumPy.

Encoding 10^6 ROS 2 messages one by one with rosbags costs more than the
rest of an export, so each message shape's byte layout is taken from
rosbags once: rosbags serialises a message whose changing fields hold
distinct marker values, the marker bytes give each field's offset, and the
values of all messages are written at those offsets with NumPy
(:class:`Layout`). Nothing of the layout is written by hand, and
:meth:`Layout.verify` encodes a message both ways and compares them byte for
byte.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any

import numpy as np

from delayform.errors import RecordingError

__all__ = ["Layout", "Slot"]

#: ``(object, attribute, code)`` of a field that changes from message to message: code ``"d"``
#: (float64), ``"i"`` (int32) or ``"I"`` (uint32)
Slot = tuple[Any, str, str]

_FORMATS = {"d": "<f8", "i": "<i4", "I": "<u4"}


def _marker(j: int, code: str) -> float | int:
    """A value whose bytes occur nowhere else in a message (distinct for each j)."""
    if code == "d":
        return 7.0e7 + 0.123456789 + 1.000000119 * j
    return 0x2D1C0B0A + 977 * j


class Layout:
    """The CDR bytes of one message, as rosbags lays them out, with the offsets of the fields that change.

    Parameters
    ----------
    store
        The rosbags type store.
    msgtype
        The message type.
    message
        A message object of that type (its other fields keep their values).
    slots
        The changing fields, in the order they are encoded.
    """

    def __init__(self, store: Any, msgtype: str, message: Any, slots: Sequence[Slot]) -> None:
        self.store, self.msgtype, self.message, self.slots = store, msgtype, message, tuple(slots)
        markers = [_marker(j, code) for j, (_, _, code) in enumerate(slots)]
        self._set(markers)
        marked = bytes(store.serialize_cdr(message, msgtype))
        # the slots come in the order they are encoded: each search starts where the last ended
        offsets, start = [], 0
        for (_, attr, code), value in zip(slots, markers):
            at = marked.find(struct.pack("<" + code, value), start)
            if at < 0:
                raise RecordingError(f"internal: cannot locate {msgtype}.{attr} in its CDR encoding")
            offsets.append(at)
            start = at + struct.calcsize(code)
        self._set([0.0 if code == "d" else 0 for _, _, code in slots])
        self.template = np.frombuffer(bytes(store.serialize_cdr(message, msgtype)), dtype=np.uint8)
        self.dtype = np.dtype({"names": [f"f{j}" for j in range(len(slots))],
                               "formats": [_FORMATS[code] for _, _, code in slots],
                               "offsets": offsets, "itemsize": self.template.size})  # fmt: skip
        self.size = int(self.template.size)
        # the markers written at those offsets into the zero message must give rosbags' marked message
        # back, byte for byte: otherwise an offset was found in the wrong place
        if self.fill([np.array([m]) for m in markers]) != marked:
            raise RecordingError(f"internal: the layout of {msgtype} found from its markers is not rosbags' encoding")

    def _set(self, values: Sequence[float | int]) -> None:
        for (obj, attr, code), value in zip(self.slots, values):
            setattr(obj, attr, float(value) if code == "d" else int(value))

    def fill(self, columns: Sequence[np.ndarray]) -> bytes:
        """The bytes of ``m`` messages back to back, field j of message r from ``columns[j].flat[r]``."""
        m = int(np.asarray(columns[0]).size)
        raw = np.tile(self.template, m)
        records = raw.view(self.dtype)
        for j, column in enumerate(columns):
            records[f"f{j}"] = np.asarray(column).reshape(-1)
        return raw.tobytes()

    def verify(self, values: Sequence[float | int]) -> None:
        """Encode one message with rosbags' own serializer and with the layout; they must agree byte for byte."""
        self._set(values)
        ours = self.fill([np.array([v]) for v in values])
        if bytes(self.store.serialize_cdr(self.message, self.msgtype)) != ours:
            raise RecordingError(f"internal: the {self.msgtype} layout disagrees with rosbags' encoding")
