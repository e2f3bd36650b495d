"""The model schema (rbody.engine.schema): each record of a params row declared once, its offsets, its checks and
its documentation in docs/design.md."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rbody import Body, Inertia, Joint, Layout, Multibody
from rbody.engine import multibody as mb
from rbody.engine import planar, records
from rbody.engine.constraints import table
from rbody.engine.schema import FLOAT, INT, Field, Record

from .trees import random_tree

DESIGN = Path(__file__).resolve().parents[3] / "docs" / "design.md"


def test_offsets_follow_the_fields_in_order():
    record = Record("r", [("a", 1, INT, ""), ("b", 3, FLOAT, ""), ("c", 2, INT, "")])
    assert record.offsets() == (0, 1, 4)
    assert record.offsets("c", "a") == (4, 0)
    assert record.size == 6
    assert list(record.integer_columns()) == [0, 4, 5]


@pytest.mark.parametrize("fields, message", [
    ([("a", 1, INT, ""), ("a", 2, FLOAT, "")], "declared twice"),
    ([("a", 0, INT, "")], "size 0"),
    ([("a", 1, "double", "")], "kind 'double'"),
])
def test_a_bad_declaration_is_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        Record("r", fields)


def test_an_unknown_field_is_named():
    with pytest.raises(ValueError, match="no field 'mass'.*'a'"):
        Record("r", [("a", 1, INT, "")]).offset("mass")


def test_the_engine_reads_the_offsets_of_its_records():
    """The constants the compiled algorithms index by are the schema's offsets, field by field."""
    assert (mb.B_TENSOR, mb.B_NJNT, mb.BODY_SIZE) == (mb.BODY.offset("tensor"), mb.BODY.offset("njnt"), mb.BODY.size)
    assert (mb.J_LINE, mb.JOINT_SIZE) == (mb.JOINT.offset("line"), mb.JOINT.size)
    assert (mb.D_PARENT, mb.DOF_SIZE) == (mb.DOF.offset("parent"), mb.DOF.size)
    assert (planar.N_LINE, planar.NODE_SIZE, planar.WORK) == (planar.NODE.offset("line"), planar.NODE.size,
                                                              planar.NODE_WORK.size)
    assert (table.U_POLY, table.UNIT_SIZE) == (table.UNIT.offset("polycoef"), table.UNIT.size)


@pytest.mark.parametrize("seed", range(5))
def test_a_compiled_tree_holds_integers_where_its_schema_says(seed):
    """Every integer field of a random tree's row is an integer, and the counts in the header match the records."""
    multibody = Multibody(random_tree(np.random.default_rng(seed), 6))
    row = np.asarray(multibody.params)
    nb, nj, nv = (int(row[k]) for k in (mb.H_BODIES, mb.H_JOINTS, mb.H_DOFS))
    for record, start, count in ((mb.BODY, int(row[mb.H_BODY]), nb), (mb.JOINT, int(row[mb.H_JOINT]), nj),
                                 (mb.DOF, int(row[mb.H_DOF]), nv)):
        block = row[start:start + count * record.size].reshape(count, record.size)
        ints = block[:, record.integer_columns()]
        assert np.array_equal(ints, np.round(ints))
    assert int(row[mb.H_DOF]) + nv * mb.DOF_SIZE == row.size
    assert sum(int(row[int(row[mb.H_BODY]) + i * mb.BODY_SIZE + mb.B_NDOF]) for i in range(nb)) == nv


def test_check_names_a_field_that_holds_no_integer():
    layout = Layout(bodies=(Body("rod", Inertia(1.0, (0, 0, -0.5), np.eye(3) * 0.1)),),
                    joints=(Joint("hinge", "hinge", "rod", axis=(0, 1, 0)),))
    row = np.array(Multibody(layout).params)
    mb.JOINT.check(row, int(row[mb.H_JOINT]), 1)  # as built: fine
    row[int(row[mb.H_JOINT]) + mb.J_QADR] = 0.5
    with pytest.raises(ValueError, match="joint record 0: integer field 'qadr' holds 0.5"):
        mb.JOINT.check(row, int(row[mb.H_JOINT]), 1)


def _documented_tables(text: str) -> dict[str, list[tuple[int, str, int, str]]]:
    """The record tables of docs/design.md: record name -> [(offset, field, size, type)]."""
    tables, name = {}, None
    for line in text.splitlines():
        heading = re.fullmatch(r"\*\*(.+)\*\* \((\d+) floats\)", line.strip())
        if heading:
            name = heading.group(1)
            tables[name] = []
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        if name is not None and len(cells) == 5 and cells[0].isdigit():
            tables[name].append((int(cells[0]), cells[1], int(cells[2]), cells[3]))
    return tables


def test_the_design_notes_print_every_record_as_declared():
    """docs/design.md's tables are `python -m rbody.engine.records`'s: regenerate them after changing a record."""
    documented = _documented_tables(DESIGN.read_text())
    for record in records.records():
        declared = [(record.offset(f.name), f.name, f.size, f.kind) for f in record.fields]
        assert documented.get(record.name) == declared, f"docs/design.md: the {record.name!r} table is stale"


def test_field_is_a_value():
    assert Field("a", 2, FLOAT, "x") == Field("a", 2, FLOAT, "x")
