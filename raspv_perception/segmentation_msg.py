"""ClassTable ↔ ``raspv_msgs/ClassNames`` (the latched ``/segmentation/classes``)."""
from __future__ import annotations

import array

import numpy as np
from raspv_msgs.msg import ClassNames
from std_msgs.msg import Header

from raspv_perception.class_table import ClassTable


def classes_to_msg(table: ClassTable, header: Header, backend: str, model: str) -> ClassNames:
    msg = ClassNames(header=header, backend=backend, model=model, label_set=table.label_set)
    msg.names = list(table.names)
    msg.synonyms = [";".join(s) for s in table.synonyms]
    msg.colors = array.array("B", np.asarray(table.colors, np.uint8).reshape(-1).tobytes())
    return msg


def classes_from_msg(msg: ClassNames) -> ClassTable:
    """The table of a ClassNames message (ValueError when its arrays do not agree)."""
    names = list(msg.names)
    synonyms = list(msg.synonyms) or [""] * len(names)
    if len(synonyms) != len(names):
        raise ValueError(f"ClassNames has {len(names)} names but {len(synonyms)} synonym entries")
    colors = np.frombuffer(bytes(msg.colors), np.uint8)
    if colors.size != 3 * len(names):
        colors = None
    entries = [n + (";" + s if s else "") for n, s in zip(names, synonyms)]
    return ClassTable.from_entries(entries, msg.label_set or "custom", colors)
