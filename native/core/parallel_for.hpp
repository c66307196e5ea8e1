// The one way the stages run a loop on OpenMP threads when its body can throw.
#pragma once
#include <atomic>
#include <exception>

namespace atlas {

// Runs body(i) for every i in [0, n), `chunk` iterations at a time on whichever
// thread is free (dynamic schedule). An exception must not leave an OpenMP
// region: it would terminate the process, and Blender with it. So the first
// one thrown (Cancelled, bad_alloc, ...) is kept, the workers skip what they
// have not started, and it is rethrown after the loop.
template <class Body>
void parallel_for(int n, int chunk, Body body) {
  std::exception_ptr error;
  std::atomic<bool> failed{false};
#pragma omp parallel for schedule(dynamic, chunk)
  for (int i = 0; i < n; ++i) {
    if (failed) continue;
    try {
      body(i);
    } catch (...) {
#pragma omp critical(atlas_parallel_for_error)
      if (!error) error = std::current_exception();
      failed = true;
    }
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace atlas
