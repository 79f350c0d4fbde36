#include "engine/learn/optim.hpp"

#include <cmath>
#include <string>

#include "engine/core/error.hpp"

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

namespace {
double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}
}  // namespace

std::vector<double> Lbfgs::direction(const std::vector<double>& grad) const {
  std::vector<double> q = grad;
  const size_t k = s_.size();
  std::vector<double> alpha(k);
  for (size_t i = k; i-- > 0;) {
    alpha[i] = dot(s_[i], q) / dot(y_[i], s_[i]);
    for (size_t j = 0; j < q.size(); ++j) q[j] -= alpha[i] * y_[i][j];
  }
  const double gamma = k ? dot(s_[k - 1], y_[k - 1]) / dot(y_[k - 1], y_[k - 1]) : 1.0;
  for (double& x : q) x *= gamma;
  for (size_t i = 0; i < k; ++i) {
    const double beta = dot(y_[i], q) / dot(y_[i], s_[i]);
    for (size_t j = 0; j < q.size(); ++j) q[j] += s_[i][j] * (alpha[i] - beta);
  }
  for (double& x : q) x = -x;
  return q;
}

void Lbfgs::update(const std::vector<double>& s, const std::vector<double>& y) {
  if (s.size() != y.size()) throw Error("Lbfgs::update: step and gradient change differ in length");
  const double sy = dot(s, y);
  if (!(sy > 1e-12 * std::sqrt(dot(s, s) * dot(y, y)))) return;
  s_.push_back(s);
  y_.push_back(y);
  if (s_.size() > memory_) {
    s_.erase(s_.begin());
    y_.erase(y_.begin());
  }
}

}  // namespace crowdmpm
