"""The bone table: the part of a skeleton glTF has no place for, kept in a skin's extras.

glTF knows joints (nodes), not bones: where each bone *ends* (a leaf's tail) is ours.
:func:`stbs.io.write_gltf` and the write-back of a character store the skeleton in
``skin.extras["stbs"]``, so that :func:`stbs.io.read_gltf` gives the same skeleton back
rather than inventing the tails again::

    {"version": 2, "C": [[x, y, z], ...], "BE": [[s, e], ...], "P": [p, ...],
     "names": [...], "joints": [node, ...]}

``joints`` is the joint node of each bone (bone ``i`` starts at joint ``joints[i]``'s
bind position). Version 1 (no ``P``, no ``joints``) is read too. Other tools ignore
the table.
"""

from __future__ import annotations

import numpy as np

from ...skeleton import Skeleton
from .container import GltfFile

__all__ = ["bone_table", "read_bone_table", "TABLE_KEY"]

TABLE_KEY = "stbs"
VERSION = 2


def bone_table(sk: Skeleton, joints: list[int]) -> dict:
    """The table of ``sk`` whose bone ``i`` starts at joint node ``joints[i]``."""
    return {"version": VERSION, "C": sk.C.tolist(), "BE": sk.BE.tolist(),
            "P": sk.parents.tolist(), "names": list(sk.names),
            "joints": [int(j) for j in joints]}


def read_bone_table(f: GltfFile, skins: list[int], joints: list[int], A: np.ndarray,
                    parent: np.ndarray, size: float) -> Skeleton | None:
    """The skeleton stored in the first of ``skins`` that has a table, checked to fit
    the file: one bone per joint of ``joints``, starting at its bind position ``A``
    (to 1e-5 of ``size``), its parent bones the joints' parents. None without a table.
    """
    for s in skins:
        skin = f.items("skins")[s]
        extras = skin.get("extras") if isinstance(skin, dict) else None
        table = extras.get(TABLE_KEY) if isinstance(extras, dict) else None
        if table is None:
            continue
        where = f"skins[{s}].extras.{TABLE_KEY}"
        j = len(joints)
        try:
            if not isinstance(table, dict) or table.get("version") not in (1, 2):
                raise ValueError("version 1 or 2")
            C = np.asarray(table["C"], dtype=float)
            BE = np.asarray(table["BE"], dtype=np.int64)
            names = [str(x) for x in table["names"]]
            nodes = table.get("joints", joints)
            P = np.asarray(table.get("P", parent), dtype=np.int64)
            ok = (C.ndim == 2 and C.shape[1] == 3 and np.isfinite(C).all()
                  and BE.shape == (j, 2) and len(names) == j and P.shape == (j,)
                  and list(nodes) == list(joints) and BE.min() >= 0 and BE.max() < len(C)
                  and np.array_equal(P, parent)
                  and np.abs(C[BE[:, 0]] - A).max() <= 1e-5 * size)
            if not ok:
                raise ValueError("a table that fits")
            return Skeleton(C, BE, names=names, P=P)
        except (KeyError, TypeError, ValueError, IndexError, OverflowError):
            raise f.error(f"{where}: a bone table (C, BE, P, names, joints) with a bone per "
                          "joint starting at its bind position, parented as the joints are",
                          "one that does not fit the file") from None
    return None
