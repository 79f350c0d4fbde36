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

}  // namespace crowdmpm
