"""job.loop_uvs: per-corner UVs of the loop triangles back onto a mesh's loops."""
import numpy as np

from atlas_defrag import job


def refuse():
    raise AssertionError("the old UVs were read, but every loop has a triangle")


def test_a_triangle_mesh_never_reads_the_old_uvs():
    tri_loops = np.array([[3, 4, 5], [0, 1, 2]], np.int32)
    uvs = np.arange(12, dtype=float).reshape(2, 3, 2)
    out, conflicts = job.loop_uvs(tri_loops, uvs, 6, refuse)
    assert conflicts == 0
    assert np.array_equal(out[[3, 4, 5, 0, 1, 2]], uvs.reshape(-1, 2))


def test_a_quad_split_between_charts_is_counted_once_per_loop():
    # A quad's two triangles share loops 0 and 2; the second gives loop 2 another UV.
    tri_loops = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    uvs = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [5, 5], [0, 1]]], float)
    out, conflicts = job.loop_uvs(tri_loops, uvs, 4, refuse)
    assert conflicts == 1
    assert np.array_equal(out[2], [5, 5])  # the last triangle's UV


def test_loops_of_no_triangle_keep_their_old_uvs():
    tri_loops = np.array([[0, 1, 2]], np.int32)
    uvs = np.ones((1, 3, 2))
    old = np.array([9, 9, 9, 9, 9, 9, 7, 8], np.float32)
    out, conflicts = job.loop_uvs(tri_loops, uvs, 4, lambda: old)
    assert conflicts == 0
    assert np.array_equal(out[3], [7, 8]) and np.array_equal(out[:3], np.ones((3, 2)))
    assert np.array_equal(job.loop_uvs(tri_loops, uvs, 4)[0][3], [0, 0])
