#pragma once
// Adam (Kingma & Ba 2015) with optional gradient-norm clipping, over a flat parameter vector.
#include <cstddef>
#include <vector>

namespace crowdmpm {

class Adam {
 public:
  explicit Adam(size_t n, double learning_rate = 1e-3, double beta1 = 0.9, double beta2 = 0.999, double eps = 1e-8);
  // Scales the gradient down to this L2 norm when it is larger (0: no clipping).
  void set_clip_norm(double c) { clip_ = c; }
  void set_learning_rate(double lr) { lr_ = lr; }
  // One update of params against grad (same length). Returns the gradient norm before clipping.
  double step(std::vector<double>& params, const std::vector<double>& grad);
  long steps() const { return t_; }

 private:
  double lr_, b1_, b2_, eps_, clip_ = 0;
  std::vector<double> m_, v_;
  long t_ = 0;
};

// Limited-memory BFGS (Nocedal & Wright, algorithm 7.4): the search direction from the last
// `memory` curvature pairs. For deterministic (full-batch) losses with ill-conditioned valleys,
// where Adam crawls along the valley floor.
class Lbfgs {
 public:
  explicit Lbfgs(size_t memory = 8) : memory_(memory) {}
  // -H grad, the quasi-Newton descent direction (-grad itself while no pair is stored).
  std::vector<double> direction(const std::vector<double>& grad) const;
  // Records a step s = x_new - x_old and the gradient change y; pairs without positive
  // curvature (s.y <= 0) are skipped.
  void update(const std::vector<double>& s, const std::vector<double>& y);
  void reset() { s_.clear(); y_.clear(); }
  bool empty() const { return s_.empty(); }

 private:
  size_t memory_;
  std::vector<std::vector<double>> s_, y_;
};

}  // namespace crowdmpm
