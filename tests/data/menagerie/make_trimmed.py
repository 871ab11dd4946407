"""Make the trimmed MuJoCo Menagerie models of this folder (kept for the record; the tests
read the ``.xml`` files, never this script).

Each model is Menagerie's MJCF (github.com/google-deepmind/mujoco_menagerie, as mink's
examples ship it) with every mesh removed so that the tests run from a fresh clone:
visual mesh geoms (``contype = conaffinity = 0``) are deleted, and each collision mesh geom
becomes a box of the mesh's bounding box (same pose, contact bits and group). Bodies,
joints, inertials (explicit in these models), sites, equality constraints, tendons,
actuators and keyframes are kept as they are. Each model's licence is beside it.

    python tests/data/menagerie/make_trimmed.py /work/ext/mink_snapshot/examples
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import mujoco
import numpy as np

#: ``output name: (Menagerie folder, model file)``.
MODELS = {
    "ur5e": ("universal_robots_ur5e", "ur5e.xml"),
    "iiwa14": ("kuka_iiwa_14", "iiwa14.xml"),
    "xarm7": ("ufactory_xarm7", "xarm7.xml"),
    "g1": ("unitree_g1", "g1.xml"),
    "h1": ("unitree_h1", "h1.xml"),
}


def trim(source: Path) -> str:
    """The MJCF text of ``source`` with its meshes replaced (see the module docstring)."""
    spec = mujoco.MjSpec.from_file(str(source))
    for mesh in spec.meshes:  # a mesh file the snapshot lacks: a small tetrahedron
        if mesh.file and not (source.parent / spec.meshdir / mesh.file).is_file():
            mesh.file = ""
            mesh.uservert = [0, 0, 0, 0.02, 0, 0, 0, 0.02, 0, 0, 0, 0.02]
    model = spec.compile()
    boxes = {}
    for g in range(model.ngeom):
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
            boxes[model.geom(g).name or g] = (centre.copy(), np.maximum(half, 1e-3))
    index = 0
    for geom in list(spec.geoms):
        key = geom.name or index
        index += 1
        if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        if geom.contype == 0 and geom.conaffinity == 0:
            spec.delete(geom)
            continue
        centre, half = boxes[key]
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, geom.quat)
        geom.pos = np.asarray(geom.pos) + rotation.reshape(3, 3) @ centre
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = half
        geom.meshname = ""
    for mesh in list(spec.meshes):
        spec.delete(mesh)
    for texture in list(spec.textures):
        spec.delete(texture)
    for material in list(spec.materials):
        material.textures = [""] * len(material.textures)
    spec.meshdir = ""
    spec.compile()
    return spec.to_xml()


def main(folder: str) -> None:
    here = Path(__file__).resolve().parent
    for name, (package, file) in MODELS.items():
        source = Path(folder) / package / file
        (here / f"{name}.xml").write_text(
            f"<!-- Trimmed from MuJoCo Menagerie's {package}/{file} by make_trimmed.py "
            f"(meshes removed); licence: LICENSE.{name} -->\n" + trim(source)
        )
        shutil.copy(Path(folder) / package / "LICENSE", here / f"LICENSE.{name}")
        print(name, "ok")


if __name__ == "__main__":
    main(sys.argv[1])
