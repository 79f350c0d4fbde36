#pragma once
// The traction network: a small MLP giving the gain K_pq >= 0 of the pair force between a
// walker p and a neighbour q (DESIGN.md section 2). Its inputs are rotation invariant.
#include <string>
#include <vector>

#include "engine/core/json_reader.hpp"

namespace crowdmpm {

enum class Activation { Identity, Tanh, Relu, Softplus, Sigmoid };

struct DenseLayer {
  int in = 0, out = 0;
  std::vector<double> weights;  // row-major out x in
  std::vector<double> biases;   // out
  Activation activation = Activation::Identity;
};

class TractionNet {
 public:
  // Input order. Pair frame: n = (x_q - x_p)/d, h = walker's desired heading, h_perp its left normal.
  static constexpr int kInputs = 6;
  static const char* const kInputNames[kInputs];  // comfort_distance, distance, ahead, side,
                                                  // closing_speed, shear_speed
  static constexpr int kMaxWidth = 64;

  // Either a constant gain (no layers) or layers ending in one output, passed through softplus
  // or relu so that K >= 0.
  double constant = 0;
  std::vector<DenseLayer> layers;
  Activation output = Activation::Softplus;

  double eval(const double* inputs) const;
  size_t parameter_count() const;

  // Flat view of the learnable values: each layer's weights (row-major) then biases, layer by
  // layer; a constant network has one value, the constant.
  std::vector<double> parameters() const;
  void set_parameters(const std::vector<double>& flat);

  // Reverse mode: evaluates K and then, for an upstream gradient dK, adds dK * dK/dinputs to
  // d_inputs[kInputs] and dK * dK/dparameters to d_params (flat order above). Exact for smooth
  // activations; relu and the constant network are handled by their (sub)gradients.
  double eval_backward(const double* inputs, double dK, double* d_inputs, double* d_params) const;

  static TractionNet parse(const JsonReader& r);
  json to_json() const;
};

double apply_activation(Activation a, double x);
double activation_derivative(Activation a, double x);  // d/dx at the pre-activation x
Activation parse_activation(const JsonReader& r, const std::string& key, const std::string& fallback);
const char* activation_name(Activation a);

}  // namespace crowdmpm
