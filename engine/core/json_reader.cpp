#include "engine/core/json_reader.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace crowdmpm {

std::string format_number(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

static std::string type_name(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::string: return "a string";
    case json::value_t::array: return "an array";
    case json::value_t::object: return "an object";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
    case json::value_t::number_float: return "a number";
    default: return "an unsupported value";
  }
}

json parse_json_text(const std::string& text, const std::string& source_name) {
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    // nlohmann's message carries "at line L, column C"; lift the position to the front so the
    // message reads like a compiler's: file:line:column: reason.
    std::string msg = e.what();
    size_t line = 0, col = 0;
    auto at = msg.find("at line ");
    if (at != std::string::npos) std::sscanf(msg.c_str() + at, "at line %zu, column %zu", &line, &col);
    auto colon = msg.find(": ", at == std::string::npos ? 0 : at);
    std::string reason = colon == std::string::npos ? msg : msg.substr(colon + 2);
    // nlohmann quotes the bytes it last read ("; last read: '...'"): drop them, so that a
    // message never echoes the contents of a file (which may not be JSON, nor the user's).
    auto quoted = reason.find("; last read:");
    if (quoted != std::string::npos) reason.erase(quoted);
    std::string where = line ? ":" + std::to_string(line) + ":" + std::to_string(col) : "";
    throw Error(source_name + where + ": invalid JSON: " + reason);
  } catch (const json::exception& e) {
    // e.g. a number too large for a double ("1e400").
    std::string msg = e.what();
    auto pos = msg.find("] ");
    throw Error(source_name + ": invalid JSON: " + (pos == std::string::npos ? msg : msg.substr(pos + 2)));
  }
}

InputPolicy input_policy(const JsonReader& request) {
  InputPolicy p;
  if (auto in = request.get("input")) {
    in->require_object();
    in->allow_only({"max_bytes", "allow_outside_paths"});
    p.max_bytes = static_cast<uint64_t>(in->in_range("max_bytes", 1, 1e15, static_cast<double>(p.max_bytes)));
    p.allow_outside_paths = in->boolean("allow_outside_paths", false);
  }
  return p;
}

json load_json_file(const std::string& path, const InputPolicy& policy) {
  return parse_json_text(read_input_file(path, policy), path);
}

void save_json_file(const json& j, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw Error("cannot write " + path);
  out << j.dump(2) << "\n";
  out.close();
  if (!out) throw Error("writing " + path + " failed");
}

std::string JsonReader::child_path(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}
std::string JsonReader::child_path(size_t index) const {
  return path_ + "[" + std::to_string(index) + "]";
}

void JsonReader::fail(const std::string& reason) const {
  throw Error((path_.empty() ? std::string("(top level)") : path_) + ": " + reason);
}
void JsonReader::fail_at(const std::string& key, const std::string& reason) const {
  throw Error(child_path(key) + ": " + reason);
}

void JsonReader::require_object() const {
  if (!value_->is_object()) fail("must be an object, got " + type_name(*value_));
}
void JsonReader::require_array() const {
  if (!value_->is_array()) fail("must be an array, got " + type_name(*value_));
}

bool JsonReader::has(const std::string& key) const {
  require_object();
  return value_->contains(key);
}

JsonReader JsonReader::at(const std::string& key) const {
  require_object();
  auto it = value_->find(key);
  if (it == value_->end()) fail_at(key, "is required but missing");
  return JsonReader(*it, child_path(key));
}

std::optional<JsonReader> JsonReader::get(const std::string& key) const {
  require_object();
  auto it = value_->find(key);
  if (it == value_->end() || it->is_null()) return std::nullopt;
  return JsonReader(*it, child_path(key));
}

JsonReader JsonReader::item(size_t index) const {
  require_array();
  return JsonReader((*value_)[index], child_path(index));
}

size_t JsonReader::size() const {
  require_array();
  return value_->size();
}

void JsonReader::allow_only(const std::vector<std::string>& keys) const {
  require_object();
  for (auto it = value_->begin(); it != value_->end(); ++it) {
    bool known = false;
    for (const auto& k : keys) known = known || k == it.key();
    if (!known) {
      std::string list;
      for (const auto& k : keys) list += (list.empty() ? "" : ", ") + k;
      fail_at(it.key(), "unknown key (allowed here: " + list + ")");
    }
  }
}

double JsonReader::as_number() const {
  if (!value_->is_number()) fail("must be a number, got " + type_name(*value_));
  double v = value_->get<double>();
  if (!std::isfinite(v)) fail("must be a finite number");
  return v;
}

std::string JsonReader::as_string() const {
  if (!value_->is_string()) fail("must be a string, got " + type_name(*value_));
  return value_->get<std::string>();
}

bool JsonReader::as_bool() const {
  if (!value_->is_boolean()) fail("must be true or false, got " + type_name(*value_));
  return value_->get<bool>();
}

Vec2 JsonReader::as_vec2() const {
  if (!value_->is_array() || value_->size() != 2)
    fail("must be a point [x, y] (two numbers, metres), got " +
         (value_->is_array() ? "an array of " + std::to_string(value_->size()) : type_name(*value_)));
  return Vec2(item(0).as_number(), item(1).as_number());
}

std::vector<Vec2> JsonReader::as_points(size_t min_count) const {
  require_array();
  if (value_->size() < min_count)
    fail("needs at least " + std::to_string(min_count) + " points, got " +
         std::to_string(value_->size()));
  std::vector<Vec2> pts;
  for (size_t i = 0; i < value_->size(); ++i) pts.push_back(item(i).as_vec2());
  return pts;
}

std::vector<double> JsonReader::as_numbers() const {
  require_array();
  std::vector<double> out;
  for (size_t i = 0; i < value_->size(); ++i) out.push_back(item(i).as_number());
  return out;
}

double JsonReader::number(const std::string& key, std::optional<double> fallback) const {
  auto r = get(key);
  if (!r) {
    if (!fallback) fail_at(key, "is required but missing");
    return *fallback;
  }
  return r->as_number();
}

double JsonReader::positive(const std::string& key, std::optional<double> fallback) const {
  double v = number(key, fallback);
  if (!(v > 0)) fail_at(key, "must be > 0, got " + format_number(v));
  return v;
}

double JsonReader::non_negative(const std::string& key, std::optional<double> fallback) const {
  double v = number(key, fallback);
  if (!(v >= 0)) fail_at(key, "must be >= 0, got " + format_number(v));
  return v;
}

double JsonReader::in_range(const std::string& key, double lo, double hi,
                            std::optional<double> fallback) const {
  double v = number(key, fallback);
  if (!(v >= lo && v <= hi))
    fail_at(key, "must be in [" + format_number(lo) + ", " + format_number(hi) + "], got " +
                     format_number(v));
  return v;
}

int JsonReader::integer(const std::string& key, long lo, long hi, std::optional<long> fallback) const {
  auto r = get(key);
  if (!r) {
    if (!fallback) fail_at(key, "is required but missing");
    return static_cast<int>(*fallback);
  }
  double v = r->as_number();
  if (v != std::floor(v)) r->fail("must be a whole number, got " + format_number(v));
  if (v < static_cast<double>(lo) || v > static_cast<double>(hi))
    r->fail("must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
            format_number(v));
  return static_cast<int>(v);
}

std::string JsonReader::string(const std::string& key, std::optional<std::string> fallback) const {
  auto r = get(key);
  if (!r) {
    if (!fallback) fail_at(key, "is required but missing");
    return *fallback;
  }
  return r->as_string();
}

std::string JsonReader::one_of(const std::string& key, const std::vector<std::string>& options,
                               std::optional<std::string> fallback) const {
  std::string v = string(key, fallback);
  for (const auto& o : options)
    if (o == v) return v;
  std::string list;
  for (const auto& o : options) list += (list.empty() ? "\"" : ", \"") + o + "\"";
  fail_at(key, "must be one of " + list + ", got \"" + v + "\"");
}

bool JsonReader::boolean(const std::string& key, std::optional<bool> fallback) const {
  auto r = get(key);
  if (!r) {
    if (!fallback) fail_at(key, "is required but missing");
    return *fallback;
  }
  return r->as_bool();
}

Vec2 JsonReader::vec2(const std::string& key, std::optional<Vec2> fallback) const {
  auto r = get(key);
  if (!r) {
    if (!fallback) fail_at(key, "is required but missing");
    return *fallback;
  }
  return r->as_vec2();
}

}  // namespace crowdmpm
