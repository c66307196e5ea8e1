// The flatten stage (thesis 5.3-5.4). Takes one aggregated chart (its original
// charts) on the cut surface. Gives FlatCharts: new UVs in texels that keep
// each triangle's shape and texel density from the old atlas (SLIM on the
// symmetric Dirichlet energy, SCAF where the boundary would cross), cut
// where it would lose density (relief_cut) and split back, undoing the last
// merge, until no piece overlaps or loses density (flatten_without_overlap);
// then strips of faces along the borders change sides where a minimum cut
// shortens the seam (straighten_borders), single faces move between
// neighbouring charts where that shortens it (refine_seams), and charts are cut where that makes them pack tighter
// (packing_cuts).
// slim, pair_cholesky, symmetric_dirichlet, tutte_embedding,
// reference_triangles, scaffold_triangulation, disk_boundary, cut_to_disk and
// relief_cut are its internals.
#pragma once
#include "flatten/flatten_chart.hpp"
#include "flatten/packing_cuts.hpp"
#include "flatten/refine_seams.hpp"
#include "flatten/slim.hpp"
#include "flatten/straighten_borders.hpp"
