// Wavefront OBJ geometry as plain arrays, read and written for the
// command-line entry (the add-on goes through Blender). Only what a textured scan needs:
// positions, texture coordinates, normals (the job moves no vertex, so they
// are written back as read), faces (triangulated) and the material each face
// uses; groups, lines and points are skipped.
#pragma once
#include <cerrno>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mesh.hpp"

namespace atlas::obj {

// A file that could not be opened, read, written or closed; errno said why (a
// missing file, a full disk). Not an InputError: nothing is wrong with the data.
// `doing` is "read" or "write".
struct FileError : std::runtime_error {
  FileError(const std::string& doing, const std::string& file, int error)
      : std::runtime_error("cannot " + doing + " " + file), path(file), error_number(error ? error : EIO) {}
  std::string path;
  int error_number;
};

struct ObjFile {
  RowMatrixX3d positions;                      // V x 3, the x y z of each `v` line (a colour after them is ignored)
  RowMatrixX2d texcoords;                      // T x 2, the u v of each `vt` line (v is 0 when absent, w ignored)
  RowMatrixX3i triangles;                      // F x 3, 0-based vertex of each corner
  RowMatrixX3i texcoord_index;                 // F x 3, 0-based texcoord of each corner; -1 on all three
                                               // corners of a face that lacks one on any corner
  RowMatrixX3d normals;                        // N x 3, the x y z of each `vn` line
  RowMatrixX3i normal_index;                   // F x 3, 0-based normal of each corner; -1 as texcoord_index
  Eigen::VectorXi face_material;               // F, index into materials; -1 before the first usemtl
  std::vector<std::string> materials;          // usemtl names, in order of first use
  std::vector<std::string> material_libraries; // mtllib arguments, in file order
  bool vertex_colours = false;                 // some `v` line has a colour after x y z (r g b, as MeshLab writes)
};

// Reads the file. Convex polygons become fans (0, i, i + 1), others are
// clipped into ears in their plane (a fan again if that fails: a polygon
// crossing itself); a face of fewer than three corners is dropped. Negative
// indices count back from the last element defined before the face, as the
// format says. A `#` starts a comment, but inside the names of `usemtl` and
// `mtllib` lines (3ds Max names materials "Material #25", and Blender reads
// the whole name); a line ending in a backslash goes on in the next one;
// lines end in \n, \r\n or \r, mixed in one file or not.
// Throws InputError naming the line for a malformed number or
// an index outside the file's elements, and FileError for a file that cannot
// be opened or read.
ObjFile read_obj(const std::string& path);

// Normals of the corners of a mesh: normal_index (F x 3) rows into normals
// (N x 3), -1 for a corner without one; both empty: no normals.
struct CornerNormals {
  RowMatrixX3d normals;
  RowMatrixX3i normal_index;
};

// Writes positions (V x 3), one `vt` per face corner (corner_uv, 3F x 2), the
// normals (`vn`, each corner naming its own; a face with a corner
// without one names none) and the faces, grouped by material in ascending
// order, each group after `usemtl materials[m]` (face_material, F, indexes
// materials), after a line `mtllib library`. Positions and normals are
// written exactly (the shortest digits that read back as the same double),
// UVs with 9 significant digits (%.9g, what a float32 holds). Throws
// FileError if the file cannot be written.
void write_obj(const std::string& path, const std::string& library, const RowMatrixX3d& positions,
               const RowMatrixX3i& triangles, const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_material,
               const std::vector<std::string>& materials, const CornerNormals& normals = {});

}  // namespace atlas::obj
