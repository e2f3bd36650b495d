"""Every record of the engine's params rows (rbody.engine.schema), in the order docs/design.md prints them.

    python -m rbody.engine.records > tables.md     # the tables of docs/design.md, "The model schema"
"""

from __future__ import annotations

from rbody.engine import elements, multibody, planar
from rbody.engine.constraints import table
from rbody.engine.schema import Record


def records() -> list[Record]:
    """The tree's header, body, joint and dof records, the planar row's, the force elements', the constraint
    block's (its contact pairs' and geoms' for the broad phase)."""
    return [multibody.TREE_HEADER, multibody.BODY, multibody.JOINT, multibody.DOF, planar.PLANAR_HEADER,
            planar.NODE, planar.NODE_WORK, elements.ELEMENTS_HEADER, elements.ACTUATOR, elements.TENDON,
            elements.PATH_ENTRY, table.CONSTRAINT_HEADER, table.UNIT, table.PAIR, table.GEOM]


def markdown() -> str:
    """The tables of every record (docs/design.md, "The model schema")."""
    return "\n\n".join(record.table() for record in records())


if __name__ == "__main__":
    print(markdown())
