#include "engine/optim.hpp"

#include <cmath>
#include <string>

#include "engine/error.hpp"

namespace crowdmpm {

Adam::Adam(size_t n, double learning_rate, double beta1, double beta2, double eps)
    : lr_(learning_rate), b1_(beta1), b2_(beta2), eps_(eps), m_(n, 0), v_(n, 0) {
  if (!(learning_rate > 0) || !(beta1 >= 0 && beta1 < 1) || !(beta2 >= 0 && beta2 < 1) || !(eps > 0))
    throw Error("Adam: learning rate and eps must be > 0, betas in [0, 1)");
}

double Adam::step(std::vector<double>& params, const std::vector<double>& grad) {
  if (params.size() != m_.size() || grad.size() != m_.size())
    throw Error("Adam: expected " + std::to_string(m_.size()) + " parameters and gradients, got " +
                std::to_string(params.size()) + " and " + std::to_string(grad.size()));
  double norm2 = 0;
  for (double g : grad) norm2 += g * g;
  const double norm = std::sqrt(norm2);
  if (!std::isfinite(norm)) throw Error("Adam: the gradient is not finite");
  const double scale = (clip_ > 0 && norm > clip_) ? clip_ / norm : 1.0;
  ++t_;
  const double c1 = 1 - std::pow(b1_, static_cast<double>(t_)), c2 = 1 - std::pow(b2_, static_cast<double>(t_));
  for (size_t i = 0; i < params.size(); ++i) {
    const double g = grad[i] * scale;
    m_[i] = b1_ * m_[i] + (1 - b1_) * g;
    v_[i] = b2_ * v_[i] + (1 - b2_) * g * g;
    params[i] -= lr_ * (m_[i] / c1) / (std::sqrt(v_[i] / c2) + eps_);
  }
  return norm;
}

}  // namespace crowdmpm
