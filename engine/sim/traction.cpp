#include "engine/sim/traction.hpp"

#include <cmath>

namespace crowdmpm {

const char* const TractionNet::kInputNames[TractionNet::kInputs] = {
    "comfort_distance", "distance", "ahead", "side", "closing_speed", "shear_speed"};

double apply_activation(Activation a, double x) {
  switch (a) {
    case Activation::Identity: return x;
    // tanh and softplus through exp and log, which glibc evaluates several times faster than
    // tanh and log1p; the absolute error stays at the 1e-16 level, all that a force gain needs.
    case Activation::Tanh: return 1 - 2 / (std::exp(2 * x) + 1);
    case Activation::Relu: return x > 0 ? x : 0;
    case Activation::Softplus: return x > 0 ? x + std::log(1 + std::exp(-x)) : std::log(1 + std::exp(x));
    case Activation::Sigmoid: return 1 / (1 + std::exp(-x));
  }
  return x;
}

double activation_derivative(Activation a, double x) {
  switch (a) {
    case Activation::Identity: return 1;
    case Activation::Tanh: {
      double t = apply_activation(Activation::Tanh, x);
      return 1 - t * t;
    }
    case Activation::Relu: return x > 0 ? 1 : 0;
    case Activation::Softplus: return 1 / (1 + std::exp(-x));  // the logistic function
    case Activation::Sigmoid: {
      double sg = 1 / (1 + std::exp(-x));
      return sg * (1 - sg);
    }
  }
  return 1;
}

const char* activation_name(Activation a) {
  switch (a) {
    case Activation::Identity: return "identity";
    case Activation::Tanh: return "tanh";
    case Activation::Relu: return "relu";
    case Activation::Softplus: return "softplus";
    case Activation::Sigmoid: return "sigmoid";
  }
  return "identity";
}

Activation parse_activation(const JsonReader& r, const std::string& key, const std::string& fallback) {
  std::string s = r.one_of(key, {"identity", "tanh", "relu", "softplus", "sigmoid"}, fallback);
  if (s == "tanh") return Activation::Tanh;
  if (s == "relu") return Activation::Relu;
  if (s == "softplus") return Activation::Softplus;
  if (s == "sigmoid") return Activation::Sigmoid;
  return Activation::Identity;
}

double TractionNet::eval(const double* inputs) const {
  if (layers.empty()) return constant;
  double a[kMaxWidth], b[kMaxWidth];
  const double* in = inputs;
  double* out = a;
  for (const auto& L : layers) {
    for (int o = 0; o < L.out; ++o) {
      double s = L.biases[o];
      const double* w = &L.weights[static_cast<size_t>(o) * L.in];
      for (int i = 0; i < L.in; ++i) s += w[i] * in[i];
      out[o] = apply_activation(L.activation, s);
    }
    in = out;
    out = (out == a) ? b : a;
  }
  return apply_activation(output, in[0]);
}

std::vector<double> TractionNet::parameters() const {
  if (layers.empty()) return {constant};
  std::vector<double> flat;
  for (const auto& L : layers) {
    flat.insert(flat.end(), L.weights.begin(), L.weights.end());
    flat.insert(flat.end(), L.biases.begin(), L.biases.end());
  }
  return flat;
}

void TractionNet::set_parameters(const std::vector<double>& flat) {
  if (flat.size() != parameter_count())
    throw Error("traction network has " + std::to_string(parameter_count()) + " parameters, got " + std::to_string(flat.size()));
  for (double v : flat)
    if (!std::isfinite(v)) throw Error("traction network parameters must be finite");
  if (layers.empty()) {
    if (flat[0] < 0) throw Error("a constant traction gain must be >= 0, got " + format_number(flat[0]));
    constant = flat[0];
    return;
  }
  size_t k = 0;
  for (auto& L : layers) {
    for (auto& w : L.weights) w = flat[k++];
    for (auto& b : L.biases) b = flat[k++];
  }
}

double TractionNet::eval_backward(const double* inputs, double dK, double* d_inputs, double* d_params) const {
  if (layers.empty()) {
    d_params[0] += dK;
    return constant;
  }
  // Forward, keeping every layer's input and pre-activation (widths are at most kMaxWidth).
  const size_t nl = layers.size();
  double act[8][kMaxWidth], pre[8][kMaxWidth];
  if (nl > 8) throw Error("traction network: backward pass supports at most 8 layers");
  const double* in = inputs;
  for (size_t l = 0; l < nl; ++l) {
    const DenseLayer& L = layers[l];
    for (int o = 0; o < L.out; ++o) {
      double z = L.biases[static_cast<size_t>(o)];
      const double* w = &L.weights[static_cast<size_t>(o) * static_cast<size_t>(L.in)];
      for (int i = 0; i < L.in; ++i) z += w[i] * in[i];
      pre[l][o] = z;
      act[l][o] = apply_activation(L.activation, z);
    }
    in = act[l];
  }
  const double K = apply_activation(output, act[nl - 1][0]);
  // Backward.
  double g[kMaxWidth], g_prev[kMaxWidth];
  g[0] = dK * activation_derivative(output, act[nl - 1][0]);
  size_t offset = parameter_count();
  for (size_t l = nl; l-- > 0;) {
    const DenseLayer& L = layers[l];
    offset -= L.weights.size() + L.biases.size();
    const double* lin = l == 0 ? inputs : act[l - 1];
    for (int i = 0; i < L.in; ++i) g_prev[i] = 0;
    for (int o = 0; o < L.out; ++o) {
      const double gz = g[o] * activation_derivative(L.activation, pre[l][o]);
      const size_t row = static_cast<size_t>(o) * static_cast<size_t>(L.in);
      for (int i = 0; i < L.in; ++i) {
        d_params[offset + row + static_cast<size_t>(i)] += gz * lin[i];
        g_prev[i] += gz * L.weights[row + static_cast<size_t>(i)];
      }
      d_params[offset + L.weights.size() + static_cast<size_t>(o)] += gz;
    }
    for (int i = 0; i < L.in; ++i) g[i] = g_prev[i];
  }
  for (int i = 0; i < kInputs; ++i) d_inputs[i] += g[i];
  return K;
}

size_t TractionNet::parameter_count() const {
  if (layers.empty()) return 1;
  size_t n = 0;
  for (const auto& L : layers) n += L.weights.size() + L.biases.size();
  return n;
}

TractionNet TractionNet::parse(const JsonReader& r) {
  r.require_object();
  r.allow_only({"constant", "inputs", "layers", "output"});
  TractionNet net;
  if (r.has("constant")) {
    if (r.has("layers") || r.has("inputs") || r.has("output"))
      r.fail("a constant gain takes no \"layers\", \"inputs\" or \"output\": give either {\"constant\": K} or a network");
    net.constant = r.non_negative("constant", std::nullopt);
    return net;
  }
  if (auto names = r.get("inputs")) {
    if (names->size() != kInputs)
      names->fail("must list the " + std::to_string(kInputs) + " network inputs in order, got " +
                  std::to_string(names->size()));
    for (size_t i = 0; i < kInputs; ++i)
      if (names->item(i).as_string() != kInputNames[i])
        names->item(i).fail(std::string("expected \"") + kInputNames[i] + "\" (inputs are fixed and ordered)");
  }
  std::string out = r.one_of("output", {"softplus", "relu"}, "softplus");
  net.output = out == "relu" ? Activation::Relu : Activation::Softplus;
  auto layers = r.at("layers");
  if (layers.size() == 0) layers.fail("needs at least one layer");
  int prev = kInputs;
  for (size_t l = 0; l < layers.size(); ++l) {
    auto L = layers.item(l);
    L.require_object();
    L.allow_only({"weights", "biases", "activation"});
    DenseLayer d;
    auto W = L.at("weights");
    d.out = static_cast<int>(W.size());
    if (d.out < 1 || d.out > kMaxWidth)
      W.fail("must have between 1 and " + std::to_string(kMaxWidth) + " rows, got " + std::to_string(d.out));
    d.in = prev;
    for (size_t o = 0; o < W.size(); ++o) {
      auto row = W.item(o);
      auto vals = row.as_numbers();
      if (static_cast<int>(vals.size()) != prev)
        row.fail("has " + std::to_string(vals.size()) + " columns but the layer input has " +
                 std::to_string(prev) + " values" + (l == 0 ? " (the network has 6 inputs)" : " (the previous layer's width)"));
      d.weights.insert(d.weights.end(), vals.begin(), vals.end());
    }
    auto B = L.at("biases");
    d.biases = B.as_numbers();
    if (static_cast<int>(d.biases.size()) != d.out)
      B.fail("has " + std::to_string(d.biases.size()) + " values but the layer has " +
             std::to_string(d.out) + " rows");
    d.activation = parse_activation(L, "activation", l + 1 == layers.size() ? "identity" : "tanh");
    prev = d.out;
    net.layers.push_back(std::move(d));
  }
  if (prev != 1) layers.item(layers.size() - 1).fail("the last layer must have 1 output (the gain K), got " + std::to_string(prev));
  return net;
}

json TractionNet::to_json() const {
  if (layers.empty()) return json{{"constant", constant}};
  json j;
  j["inputs"] = json::array();
  for (auto n : kInputNames) j["inputs"].push_back(n);
  j["output"] = activation_name(output);
  j["layers"] = json::array();
  for (const auto& L : layers) {
    json W = json::array();
    for (int o = 0; o < L.out; ++o)
      W.push_back(std::vector<double>(L.weights.begin() + o * L.in, L.weights.begin() + (o + 1) * L.in));
    j["layers"].push_back({{"weights", W}, {"biases", L.biases}, {"activation", activation_name(L.activation)}});
  }
  return j;
}

}  // namespace crowdmpm
