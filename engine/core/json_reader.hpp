#pragma once
// Validating reader over nlohmann::json that knows the JSON path of every value it reads, so
// that every complaint names where it is: "groups[1].spawn.density: must be > 0, got -2".
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "engine/core/error.hpp"
#include "engine/core/input.hpp"
#include "engine/core/vec.hpp"

namespace crowdmpm {

using json = nlohmann::json;

// Parses JSON text; a syntax error is reported with the file name, line and column.
json parse_json_text(const std::string& text, const std::string& source_name);
json load_json_file(const std::string& path, const InputPolicy& policy = {});
// Writes j (indented, with a final newline) to path; throws Error naming the path if it cannot.
void save_json_file(const json& j, const std::string& path);

class JsonReader {
 public:
  JsonReader(const json& value, std::string path) : value_(&value), path_(std::move(path)) {}

  const json& value() const { return *value_; }
  const std::string& path() const { return path_; }
  std::string child_path(const std::string& key) const;
  std::string child_path(size_t index) const;

  [[noreturn]] void fail(const std::string& reason) const;
  [[noreturn]] void fail_at(const std::string& key, const std::string& reason) const;

  bool has(const std::string& key) const;
  JsonReader at(const std::string& key) const;  // required member
  std::optional<JsonReader> get(const std::string& key) const;
  JsonReader item(size_t index) const;
  size_t size() const;  // array length; fails if not an array

  void require_object() const;
  void require_array() const;
  // Rejects members other than those listed: a typo in a key is an error, not a silent default.
  void allow_only(const std::vector<std::string>& keys) const;

  double as_number() const;
  std::string as_string() const;
  bool as_bool() const;
  Vec2 as_vec2() const;
  std::vector<Vec2> as_points(size_t min_count) const;
  std::vector<double> as_numbers() const;

  // Members with defaults and range checks.
  double number(const std::string& key, std::optional<double> fallback) const;
  double positive(const std::string& key, std::optional<double> fallback) const;
  double non_negative(const std::string& key, std::optional<double> fallback) const;
  double in_range(const std::string& key, double lo, double hi, std::optional<double> fallback) const;
  int integer(const std::string& key, long lo, long hi, std::optional<long> fallback) const;
  std::string string(const std::string& key, std::optional<std::string> fallback) const;
  std::string one_of(const std::string& key, const std::vector<std::string>& options,
                     std::optional<std::string> fallback) const;
  bool boolean(const std::string& key, std::optional<bool> fallback) const;
  Vec2 vec2(const std::string& key, std::optional<Vec2> fallback) const;

 private:
  const json* value_;
  std::string path_;
};

std::string format_number(double v);

// A job request's optional "input": {"max_bytes": N, "allow_outside_paths": bool} (InputPolicy).
InputPolicy input_policy(const JsonReader& request);

}  // namespace crowdmpm
