// The flatten stage (thesis 5.3-5.4). Takes the aggregation on the cut
// surface. Gives FlatCharts: new UVs in texels that keep each triangle's
// shape and texel density from the old atlas (SLIM on the symmetric
// Dirichlet energy, SCAF where the boundary would cross), cut where they
// would lose density (relief_cut) and split back, undoing the last merge,
// until no piece overlaps or loses density (flatten_without_overlap), under
// the density rule over the whole surface (flatten_aggregation); then strips
// of faces along the borders change sides where a minimum cut shortens the
// seam (straighten_borders), single faces move between neighbouring charts
// where that shortens it (refine_seams), squeezed faces at the final borders
// are relaxed (relax_squeezed_borders), and charts are cut where that makes
// them pack tighter (packing_cuts). slim.hpp is public for its options and
// the solve of one chart; reference_triangles.hpp for the flat triangle a
// face detached from its chart takes. pair_cholesky, supernodal_cholesky,
// sparse_cholesky, elimination_tree, symmetric_dirichlet, tutte_embedding,
// scaffold_triangulation, disk_boundary, cut_to_disk, fill_holes,
// relief_cut, relax_squeezed_faces and chart_rows are its internals.
#pragma once
#include "flatten/flatten_aggregation.hpp"
#include "flatten/flatten_without_overlap.hpp"
#include "flatten/packing_cuts.hpp"
#include "flatten/reference_triangles.hpp"
#include "flatten/refine_seams.hpp"
#include "flatten/relax_squeezed_borders.hpp"
#include "flatten/slim.hpp"
#include "flatten/straighten_borders.hpp"
