"""Random meshes written as OBJ in every index form parse back to the same arrays."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from meshtool.read.obj.parse import parse_obj

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, width=64)


@st.composite
def meshes(draw):
    nv = draw(st.integers(3, 30))
    positions = draw(arrays(np.float64, (nv, 3), elements=finite))
    nt = draw(st.integers(1, 10))
    texcoords = draw(arrays(np.float64, (nt, 2), elements=finite))
    nn = draw(st.integers(1, 5))
    normals = draw(arrays(np.float64, (nn, 3), elements=finite))
    nf = draw(st.integers(1, 20))
    sizes = draw(st.lists(st.integers(3, 6), min_size=nf, max_size=nf))
    corners = sum(sizes)
    v = draw(arrays(np.int64, corners, elements=st.integers(0, nv - 1)))
    vt = draw(arrays(np.int64, corners, elements=st.integers(0, nt - 1)))
    vn = draw(arrays(np.int64, corners, elements=st.integers(0, nn - 1)))
    form = draw(st.sampled_from(["v", "v/vt", "v//vn", "v/vt/vn"]))
    negative = draw(st.booleans())
    crlf = draw(st.booleans())
    return positions, texcoords, normals, np.asarray(sizes), v, vt, vn, form, negative, crlf


def write(positions, texcoords, normals, sizes, v, vt, vn, form, negative, crlf):
    lines = [f"v {a!r} {b!r} {c!r}" for a, b, c in positions.tolist()]
    lines += [f"vt {a!r} {b!r}" for a, b in texcoords.tolist()]
    lines += [f"vn {a!r} {b!r} {c!r}" for a, b, c in normals.tolist()]
    counts = (len(positions), len(texcoords), len(normals))

    def ref(i, n):
        return str(i - n) if negative else str(i + 1)

    k = 0
    for size in sizes.tolist():
        words = []
        for c in range(k, k + size):
            a, b, n = ref(v[c], counts[0]), ref(vt[c], counts[1]), ref(vn[c], counts[2])
            words.append({"v": a, "v/vt": f"{a}/{b}", "v//vn": f"{a}//{n}", "v/vt/vn": f"{a}/{b}/{n}"}[form])
        lines.append("f " + " ".join(words))
        k += size
    return ("\r\n" if crlf else "\n").join(lines) + "\n"


@settings(max_examples=150, deadline=None)
@given(meshes())
def test_round_trip_every_index_form(mesh):
    positions, texcoords, normals, sizes, v, vt, vn, form, _, _ = mesh
    obj = parse_obj(write(*mesh).encode())
    np.testing.assert_array_equal(obj.positions, positions)
    np.testing.assert_array_equal(obj.texcoords, texcoords)
    np.testing.assert_array_equal(obj.normals, normals)
    np.testing.assert_array_equal(obj.face_sizes, sizes)
    np.testing.assert_array_equal(obj.corner_v, v)
    np.testing.assert_array_equal(obj.corner_vt, vt if "vt" in form else np.full(v.shape, -1))
    np.testing.assert_array_equal(obj.corner_vn, vn if "vn" in form else np.full(v.shape, -1))
