#include "engine/core/parallel.hpp"

#include <chrono>

#include "engine/core/error.hpp"

namespace crowdmpm {

ThreadPool::ThreadPool(int threads) {
  if (threads < 1 || threads > 256)
    throw Error("thread count must be in [1, 256], got " + std::to_string(threads));
  try {
    for (int i = 1; i < threads; ++i) workers_.emplace_back([this, i] { worker(i); });
  } catch (const std::exception& e) {
    // Join the workers that did start, or their destruction would terminate the process.
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    start_cv_.notify_all();
    for (auto& t : workers_) t.join();
    throw Error("cannot start " + std::to_string(threads) + " threads: " + e.what());
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_cv_.notify_all();
  for (auto& t : workers_) t.join();
}

namespace {
// How long a thread polls before it blocks: long enough to cover the gap between the loops of
// one step, short enough not to burn a core that an oversubscribed machine needs.
constexpr auto kSpin = std::chrono::microseconds(50);

template <class Pred>
bool spin_until(Pred ready) {
  auto until = std::chrono::steady_clock::now() + kSpin;
  for (int i = 0;; ++i) {
    if (ready()) return true;
    if ((i & 63) == 63 && std::chrono::steady_clock::now() > until) return false;
  }
}
}  // namespace

static void chunk(size_t n, int parts, int index, size_t& begin, size_t& end) {
  size_t base = n / parts, extra = n % parts;
  size_t i = static_cast<size_t>(index);
  begin = i * base + std::min(i, extra);
  end = begin + base + (i < extra ? 1 : 0);
}

void ThreadPool::worker(int index) {
  unsigned long seen = 0;
  for (;;) {
    const Task* task;
    size_t n;
    spin_until([&] { return generation_.load(std::memory_order_acquire) != seen; });
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_cv_.wait(lock, [&] { return stop_ || generation_.load() != seen; });
      if (stop_) return;
      seen = generation_.load();
      task = task_;
      n = n_;
    }
    size_t b, e;
    chunk(n, threads(), index, b, e);
    std::exception_ptr err;
    try {
      if (b < e) task->call(task->fn, b, e);
    } catch (...) {
      err = std::current_exception();
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (err && !error_) error_ = err;
      if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) done_cv_.notify_one();
    }
  }
}

void ThreadPool::run(size_t n, const Task& fn, size_t min_parallel) {
  if (workers_.empty() || n < std::max<size_t>(min_parallel, 2)) {
    if (n) fn.call(fn.fn, 0, n);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    task_ = &fn;
    n_ = n;
    pending_.store(static_cast<int>(workers_.size()));
    error_ = nullptr;
    generation_.fetch_add(1, std::memory_order_release);
  }
  start_cv_.notify_all();
  size_t b, e;
  chunk(n, threads(), 0, b, e);
  std::exception_ptr err;
  try {
    if (b < e) fn.call(fn.fn, b, e);
  } catch (...) {
    err = std::current_exception();
  }
  spin_until([&] { return pending_.load(std::memory_order_acquire) == 0; });
  std::unique_lock<std::mutex> lock(mutex_);
  done_cv_.wait(lock, [&] { return pending_.load() == 0; });
  if (!err) err = error_;
  task_ = nullptr;
  if (err) std::rethrow_exception(err);
}

}  // namespace crowdmpm
