#pragma once
// A small persistent thread pool. Kernels use it only as parallel_for over disjoint index
// ranges whose outputs do not overlap, so results are bitwise identical for any thread count.
#include <atomic>
#include <condition_variable>
#include <type_traits>
#include <mutex>
#include <thread>
#include <vector>

namespace crowdmpm {

class ThreadPool {
 public:
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }
  // Calls fn(begin, end) on contiguous chunks of [0, n); returns when all are done. An exception
  // thrown by fn is rethrown here (the first one). Loops shorter than min_parallel run on the
  // calling thread (waking workers costs more than a few cheap items); pass 1 when each item
  // is large (a block of grid rows).
  template <class F>
  void parallel_for(size_t n, F&& fn, size_t min_parallel = 64) {
    // A reference to the callable, not a std::function: no allocation per call.
    Task t{&fn, [](void* f, size_t b, size_t e) { (*static_cast<std::remove_reference_t<F>*>(f))(b, e); }};
    run(n, t, min_parallel);
  }

 private:
  struct Task {
    void* fn;
    void (*call)(void*, size_t, size_t);
  };
  void run(size_t n, const Task& task, size_t min_parallel);
  void worker(int index);
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_cv_, done_cv_;
  const Task* task_ = nullptr;
  size_t n_ = 0;
  // Workers spin briefly on generation_ before sleeping, and the caller spins on pending_: a
  // step launches about a dozen loops, and waking a sleeping thread costs tens of microseconds.
  std::atomic<unsigned long> generation_{0};
  std::atomic<int> pending_{0};
  bool stop_ = false;
  std::exception_ptr error_;
};

}  // namespace crowdmpm
