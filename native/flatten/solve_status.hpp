// How a flattening solve ended: one value type instead of an empty string
// for success, so that callers branch on the kind and people read the detail.
#pragma once
#include <string>
#include <utility>

namespace atlas {

enum class SolveFailure {
  none,        // solved
  bad_input,   // arrays of the wrong shape
  not_disk,    // the faces are not a topological disk
  embedding,   // the initial (mean-value) embedding failed or folds over
  system,      // a linear system broke down (not positive definite, non-finite)
  round_off,   // a step flipped a face in round-off
  scaffold,    // SCAF found no scaffold around the boundary
};

struct SolveStatus {
  SolveFailure failure = SolveFailure::none;
  std::string detail;  // why, for people; empty when solved

  bool ok() const { return failure == SolveFailure::none; }
};

inline SolveStatus solve_failed(SolveFailure failure, std::string detail) { return {failure, std::move(detail)}; }

}  // namespace atlas
