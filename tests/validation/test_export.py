"""The checked-in models/ are exactly what the exporter writes today, and MuJoCo compiles each with
rbody's mass properties."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from validation.__main__ import MODELS_DIR, main
from validation.export import models


def test_regenerated_models_equal_the_checked_in_ones(tmp_path):
    assert main(["export", "--out", str(tmp_path)]) == 0
    written = {p.name: p.read_text() for p in tmp_path.glob("*.xml")}
    checked_in = {p.name: p.read_text() for p in Path(MODELS_DIR).glob("*.xml")}
    assert written, "the exporter wrote no model"
    assert sorted(written) == sorted(checked_in), "models/ is out of date: run python -m validation export"
    for name, text in written.items():
        assert text == checked_in[name], f"models/{name} differs from the exporter's output: regenerate it"


@pytest.mark.parametrize("name", sorted(models()))
def test_each_model_compiles_with_rbodys_masses(name):
    from validation.cases import default_cases

    case = next(c for c in default_cases() if c.name == name)
    model = mujoco.MjModel.from_xml_string(models()[name])
    for body in case.scene.layout.bodies:
        index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body.name)
        assert index >= 0
        assert model.body_mass[index] == pytest.approx(body.inertia.mass, rel=1e-12)
        np.testing.assert_allclose(model.body_ipos[index], body.inertia.com, rtol=1e-12, atol=1e-15)
