// Progress reporting and cooperative cancellation shared by every stage.
// One RunControl is owned by the caller of a pipeline run; stages only borrow it.
#pragma once
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

namespace atlas {

// Thrown when the caller asked to stop; the pipeline leaves its inputs untouched.
struct Cancelled : std::runtime_error {
  Cancelled() : std::runtime_error("cancelled") {}
};

class RunControl {
 public:
  // report(stage, fraction in [0,1]) may run on any thread, one call at a
  // time (see progress_from_worker): it takes whatever lock its target needs
  // (the Python binding takes the GIL).
  using ReportFn = std::function<void(const std::string& stage, double fraction)>;

  using Flag = std::shared_ptr<std::atomic<bool>>;

  RunControl() = default;
  // flag may be shared with the caller (e.g. a Python CancelToken) to cancel from outside.
  explicit RunControl(ReportFn report, Flag flag = std::make_shared<std::atomic<bool>>(false))
      : report_(std::move(report)), cancelled_(std::move(flag)) {}

  // const: cancelling is a signal to the run, not a change of its inputs.
  void cancel() const { cancelled_->store(true, std::memory_order_relaxed); }
  bool cancelled() const { return cancelled_->load(std::memory_order_relaxed); }

  // Safe to call from any thread: OpenMP workers poll cancelled() instead.
  void throw_if_cancelled() const {
    if (cancelled()) throw Cancelled();
  }

  // Forwards progress (see ReportFn), then honours a pending cancel.
  void progress(const std::string& stage, double fraction) const {
    if (report_) report_(stage, fraction);
    throw_if_cancelled();
  }

  // progress() from one of a stage's worker threads: one report at a time
  // per run, and none waited for (progress is advice). A lock shared by all
  // runs would deadlock a report that itself starts a run.
  void progress_from_worker(const std::string& stage, double fraction) const {
    {
      std::unique_lock<std::mutex> lock(*reporting_, std::try_to_lock);
      if (lock.owns_lock() && report_) report_(stage, fraction);
    }
    throw_if_cancelled();
  }

 private:
  ReportFn report_;
  Flag cancelled_ = std::make_shared<std::atomic<bool>>(false);
  std::shared_ptr<std::mutex> reporting_ = std::make_shared<std::mutex>();
};

}  // namespace atlas
