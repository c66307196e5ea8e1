// Parameterization of one merged chart (thesis 3.4.5, 5.3-5.4): a flip-free
// initial embedding, then SLIM on the symmetric Dirichlet energy of the map
// from each face's ORIGINAL UV triangle (the reference) to its new one.
#pragma once

#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "flatten/relax_squeezed_faces.hpp"
#include "flatten/solve_status.hpp"

namespace atlas {

// One chart, in local vertex numbering. The faces form a consistently
// oriented topological disk (cut_to_disk makes sure of it).
struct ChartProblem {
  RowMatrixX3i triangles;        // F x 3, local vertex indices 0..n-1
  RowMatrixX3d positions;        // n x 3, 3D positions (used to repair references)
  RowMatrixX2d reference_uv;     // 3F x 2, the face's original UV triangle in texels
  Eigen::VectorXi mirrored;      // F, 1 where the face's original chart is mirrored
};

struct SlimOptions {
  // SLIM and SCAF (see below) each get max_iterations, and so does each
  // round of the density repair; 0 leaves the initial embedding as it is.
  int max_iterations = 60;
  // Stop when (E_k - E_k+1) / E_k falls below: tighter costs time for little
  // (bench/README.md); 0 runs every iteration.
  double relative_tolerance = 1e-2;
  // Keeps the proxy system definite (the translation the energy does not
  // see); with 0 the factorization retries with a weight of its own
  // (factorize_proxy).
  double proximal_weight = 1e-4;
  // A step after which the boundary crosses itself is undone, and the solve
  // goes on inside a scaffold (SCAF, Jiang et al. 2017) that cannot cross.
  // Slower per iteration (the scaffold, so the pattern, is rebuilt every 8
  // steps), but it spares splitting the chart. false: plain SLIM, which never
  // looks at the boundary and may leave it crossing itself.
  bool scaffold_on_crossing = true;
  // SLIM first aims at intermediate references whose symmetric Dirichlet
  // energy from the current map stays below this bound on every face (see
  // slim.cpp); 4 is isometric. 0: the real references from the start.
  double progressive_bound = 48;
  // Density repair: SLIM balances distortion, it does not bound it, so a few
  // faces can end squeezed below half their texels. Each face left below
  // repair_floor of its reference area, at ratio r, then weighs
  // repair_factor * repair_floor / r times more and the solve goes on from
  // where it stopped, up to repair_rounds times. 0 rounds: no repair. One
  // round, because the local relaxation after it (relax below) lifts most
  // of what a second round would, for a smaller chart and less time.
  int repair_rounds = 1;
  // Only charts with more than this share of their reference area below half
  // are repaired: below it the repair costs more time than the detail it
  // saves is worth (bench/README.md). 0: every chart with such a face. The
  // pipeline lowers it to the density loss budget (PipelineOptions).
  double repair_share = 0.01;
  // The weights above; a floor a little over one half lifts faces clear of
  // the density rule's line. 0 for either: no repair.
  double repair_floor = 0.55;
  double repair_factor = 4;
  // A repair round that raises the chart's energy per unit reference area (4
  // is isometric) above this and above where the repair started is undone,
  // and a chart already above it is not repaired: the squeeze then spreads over the chart
  // and costs more detail than it saves (bench/README.md). 0: no repair.
  double repair_energy_bound = 5.5;
  // Then the faces still below half their area, with the vertices near them
  // relaxed and the rest held (relax_squeezed_faces.hpp; sweeps 0: not).
  RelaxOptions relax;
};

struct ChartSolution {
  RowMatrixX2d uv;             // n x 2 new positions in texels (arbitrary placement)
  double energy_initial = 0;   // per unit reference area, at the initial embedding
  double energy_final = 0;     // per unit reference area; 4 is the isometric minimum
  int iterations = 0;          // every SLIM and SCAF iteration, those of undone repair rounds too
  bool scaffolded = false;     // the boundary crossed itself once and SCAF took over
  bool density_repaired = false;  // the density repair moved the solution (SlimOptions::repair_rounds)
  // Wall time of the plain SLIM iterations, and of the numeric Cholesky
  // factorizations within them: the benchmark reports their ratio.
  double iteration_seconds = 0, factorize_seconds = 0;
  int flipped = 0;             // faces with non-positive signed area in uv
  int folded_references = 0;   // references folded over inside their original chart (mirror image used)
  int repaired_references = 0; // degenerate references replaced by a well-shaped triangle
  SolveStatus status;          // not ok: why the result is unusable
};

// Solves one chart. Never throws on bad geometry: problems are reported in
// ChartSolution::status. Throws Cancelled if control is cancelled.
// uv and the energies are always finite: when the status is not ok, uv is the last
// flip-free iterate, or the initial map (flipped > 0) if that already folds, or
// zeros if the problem is malformed, the chart is not a disk or it has no
// embedding; energies stay 0 until a flip-free map exists.
// Thread-safe; meant to be called concurrently, one chart per thread.
ChartSolution parameterize_chart(const ChartProblem& problem, const SlimOptions& options,
                                 const RunControl& control);

}  // namespace atlas
