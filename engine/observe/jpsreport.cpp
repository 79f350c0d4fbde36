#include "engine/observe/jpsreport.hpp"

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>

#include "engine/core/error.hpp"
#include "engine/core/input.hpp"

namespace crowdmpm {

namespace fs = std::filesystem;

namespace {

// The little XML JPSreport writes: elements with attributes, comments, declarations. Text
// content is ignored.
struct Element {
  std::string name;
  std::map<std::string, std::string> attrs;
  std::vector<std::unique_ptr<Element>> children;
  int line = 0;

  std::vector<const Element*> all(const std::string& n) const {  // descendants named n, in order
    std::vector<const Element*> out;
    for (const auto& c : children) {
      if (c->name == n) out.push_back(c.get());
      for (const Element* d : c->all(n)) out.push_back(d);
    }
    return out;
  }
  const Element* first(const std::string& n) const {
    auto v = all(n);
    return v.empty() ? nullptr : v.front();
  }
};

class XmlReader {
 public:
  static constexpr size_t kMaxDepth = 64;  // JPSreport files nest 5 deep; a cap keeps recursion bounded

  XmlReader(const std::string& text, std::string source) : s_(text), source_(std::move(source)) {}

  std::unique_ptr<Element> parse() {
    auto root = std::make_unique<Element>();
    root->name = "#document";
    std::vector<Element*> stack{root.get()};
    while (i_ < s_.size()) {
      if (s_[i_] != '<') {
        advance();
        continue;
      }
      if (s_.compare(i_, 4, "<!--") == 0) {
        skip_past("-->");
      } else if (s_.compare(i_, 2, "<?") == 0 || s_.compare(i_, 2, "<!") == 0) {
        skip_past(">");
      } else if (s_.compare(i_, 2, "</") == 0) {
        advance(2);
        const std::string name = read_name();
        skip_space();
        expect('>');
        if (stack.size() < 2 || stack.back()->name != name) fail("closing tag </" + name + "> does not match");
        stack.pop_back();
      } else {
        advance();
        auto e = std::make_unique<Element>();
        e->line = line_;
        e->name = read_name();
        if (e->name.empty()) fail("a tag without a name");
        bool closed = false;
        for (;;) {
          skip_space();
          if (i_ >= s_.size()) fail("unterminated tag <" + e->name + ">");
          if (s_[i_] == '/') {
            advance();
            expect('>');
            closed = true;
            break;
          }
          if (s_[i_] == '>') {
            advance();
            break;
          }
          const std::string key = read_name();
          if (key.empty()) fail("a malformed attribute in <" + e->name + ">");
          skip_space();
          expect('=');
          skip_space();
          if (i_ >= s_.size() || (s_[i_] != '"' && s_[i_] != '\'')) fail("attribute " + key + " needs a quoted value");
          const char q = s_[i_];
          advance();
          const size_t end = s_.find(q, i_);
          if (end == std::string::npos) fail("unterminated value of attribute " + key);
          e->attrs[key] = s_.substr(i_, end - i_);
          advance(end - i_ + 1);
        }
        Element* raw = e.get();
        stack.back()->children.push_back(std::move(e));
        if (!closed) stack.push_back(raw);
        if (stack.size() > kMaxDepth) fail("elements nested deeper than " + std::to_string(kMaxDepth));
      }
    }
    if (stack.size() != 1) fail("<" + stack.back()->name + "> is never closed");
    return root;
  }

 private:
  void advance(size_t n = 1) {
    for (size_t k = 0; k < n && i_ < s_.size(); ++k, ++i_)
      if (s_[i_] == '\n') ++line_;
  }
  void skip_space() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) advance();
  }
  void skip_past(const char* token) {
    const size_t end = s_.find(token, i_);
    if (end == std::string::npos) fail(std::string("no closing ") + token);
    advance(end - i_ + std::char_traits<char>::length(token));
  }
  void expect(char c) {
    if (i_ >= s_.size() || s_[i_] != c) fail(std::string("expected '") + c + "'");
    advance();
  }
  std::string read_name() {
    const size_t b = i_;
    while (i_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[i_])) || s_[i_] == '_' || s_[i_] == '-' ||
                              s_[i_] == ':' || s_[i_] == '.'))
      advance();
    return s_.substr(b, i_ - b);
  }
  [[noreturn]] void fail(const std::string& why) const { throw Error(source_ + ":" + std::to_string(line_) + ": " + why); }

  const std::string& s_;
  std::string source_;
  size_t i_ = 0;
  int line_ = 1;
};

double number_attr(const Element& e, const std::string& key, const std::string& source) {
  auto it = e.attrs.find(key);
  if (it == e.attrs.end())
    throw Error(source + ":" + std::to_string(e.line) + ": <" + e.name + "> lacks the attribute " + key);
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (it->second.empty() || *end != '\0' || !std::isfinite(v))
    throw Error(source + ":" + std::to_string(e.line) + ": <" + e.name + "> " + key + "=\"" + it->second + "\" is not a number");
  return v;
}

std::string attr(const Element& e, const std::string& key, const std::string& fallback = "") {
  auto it = e.attrs.find(key);
  return it == e.attrs.end() ? fallback : it->second;
}

Polygon2 vertices(const Element& e, const char* xk, const char* yk, const std::string& source) {
  Polygon2 p;
  for (const Element* v : e.all("vertex")) p.emplace_back(number_attr(*v, xk, source), number_attr(*v, yk, source));
  if (p.size() > 1 && (p.front() - p.back()).norm() < 1e-9) p.pop_back();  // a closed ring lists its start twice
  return p;
}

std::string safe_id(const std::string& prefix, const std::string& id) {
  std::string out = prefix;
  for (char c : id) out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
  return out;
}

}  // namespace

JpsreportProject read_jpsreport_project(const std::string& ini_arg, const InputPolicy& policy) {
  std::string ini = ini_arg;
  if (fs::is_directory(ini)) ini = (fs::path(ini) / "ini.xml").string();
  const std::string text = read_input_file(ini, policy);
  const auto doc = XmlReader(text, ini).parse();
  const Element* root = doc->first("JPSreport");
  if (!root) throw Error(ini + ": not a JPSreport project file (no <JPSreport> element)");
  const fs::path base = fs::path(ini).parent_path();
  JpsreportProject p;
  // Trajectories: <trajectories><file name=.../><path location=.../></trajectories>.
  const Element* traj = root->first("trajectories");
  const Element* file = traj ? traj->first("file") : nullptr;
  if (!file || attr(*file, "name").empty()) throw Error(ini + ": no <trajectories><file name=\"...\"/> element");
  const Element* loc = traj->first("path");
  const std::string folder = base.empty() ? "." : base.string();
  p.trajectories = confined_path(folder, folder, (fs::path(loc ? attr(*loc, "location", ".") : ".") / attr(*file, "name")).string(),
                                 policy, ini + ": <trajectories>");
  if (traj->first("file") != traj->all("file").back()) p.notes.push_back("only the first trajectory file of " + ini + " is read");
  // Measurement areas and lines.
  for (const Element* a : root->all("area_B")) {
    Polygon2 poly = vertices(*a, "x", "y", ini);
    if (poly.size() < 3) throw Error(ini + ":" + std::to_string(a->line) + ": <area_B> needs at least 3 vertices");
    p.spec.areas.push_back({safe_id("area", attr(*a, "id")), poly});
  }
  for (const Element* l : root->all("area_L")) {
    const Element* s = l->first("start");
    const Element* e = l->first("end");
    if (!s || !e) throw Error(ini + ":" + std::to_string(l->line) + ": <area_L> needs <start> and <end>");
    p.spec.lines.push_back({safe_id("line", attr(*l, "id")), Vec2(number_attr(*s, "x", ini), number_attr(*s, "y", ini)),
                            Vec2(number_attr(*e, "x", ini), number_attr(*e, "y", ini))});
  }
  if (p.spec.areas.empty() && p.spec.lines.empty()) throw Error(ini + ": no <area_B> or <area_L> to measure");
  p.spec.check_unique_ids(ini);
  // JPSreport takes half its frame_step on each side of a frame.
  if (const Element* v = root->first("velocity")) {
    const double fs_ = number_attr(*v, "frame_step", ini);
    if (!(fs_ >= 2 && fs_ <= 2000))
      throw Error(ini + ":" + std::to_string(v->line) + ": <velocity frame_step> must be in [2, 2000], got " + attr(*v, "frame_step"));
    p.spec.frame_step = static_cast<long>(fs_) / 2;
    if (attr(*v, "set_movement_direction", "None") != "None")
      p.notes.push_back("<velocity set_movement_direction> is ignored: speeds are the norm of the velocity");
  }
  // <method_D><cut_by_circle enabled="true" radius edges/>: the Voronoi cut-off.
  for (const Element* c : root->all("cut_by_circle"))
    if (attr(*c, "enabled") == "true") {
      p.spec.cutoff_radius = number_attr(*c, "radius", ini);
      p.spec.cutoff_edges = static_cast<int>(number_attr(*c, "edges", ini));
      if (!(p.spec.cutoff_radius > 0 && p.spec.cutoff_radius <= 100) || p.spec.cutoff_edges < 3 || p.spec.cutoff_edges > 1000)
        throw Error(ini + ":" + std::to_string(c->line) + ": <cut_by_circle> needs radius in (0, 100] m and edges in [3, 1000]");
    }
  // Geometry: the polygon of the (single) subroom is the walkable area.
  if (const Element* g = root->first("geometry")) {
    if (attr(*g, "file").empty()) throw Error(ini + ":" + std::to_string(g->line) + ": <geometry> has no file attribute");
    const std::string geo_path = confined_path(folder, folder, attr(*g, "file"), policy, ini + ": <geometry>");
    const std::string geo_text = read_input_file(geo_path, policy);
    const auto geo = XmlReader(geo_text, geo_path).parse();
    std::vector<Polygon2> rings;
    for (const Element* poly : geo->all("polygon")) {
      rings.push_back(vertices(*poly, "px", "py", geo_path));
      if (rings.back().size() < 2)
        throw Error(geo_path + ":" + std::to_string(poly->line) + ": <polygon> needs at least 2 vertices");
    }
    if (rings.size() == 1 && geo->all("obstacle").empty()) {
      p.spec.walkable = rings.front();
    } else if (!rings.empty()) {
      Vec2 lo = rings[0][0], hi = lo;
      for (const auto& r : rings)
        for (const Vec2& q : r) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
      p.spec.walkable = {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())};
      p.notes.push_back(geo_path + ": " + std::to_string(rings.size()) +
                        " wall polygons or obstacles; Voronoi cells are clipped by their bounding box only");
    }
    if (!p.spec.walkable.empty()) triangulate(p.spec.walkable, geo_path + ": the walkable polygon");
  } else {
    p.notes.push_back(ini + ": no <geometry>: Voronoi cells are clipped by the trajectories' bounding box grown by 1 m");
  }
  return p;
}

}  // namespace crowdmpm
