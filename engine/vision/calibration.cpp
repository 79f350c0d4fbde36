#include "engine/vision/calibration.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "engine/core/error.hpp"

namespace crowdmpm {

namespace {

std::array<double, 9> invert(const std::array<double, 9>& m) {
  cv::Matx33d a(m.data());
  cv::Matx33d b = a.inv();
  std::array<double, 9> r;
  for (int i = 0; i < 9; ++i) r[static_cast<size_t>(i)] = b.val[i];
  return r;
}

Vec2 apply(const std::array<double, 9>& H, const Vec2& p, double* w_out = nullptr) {
  const double x = H[0] * p.x() + H[1] * p.y() + H[2];
  const double y = H[3] * p.x() + H[4] * p.y() + H[5];
  const double w = H[6] * p.x() + H[7] * p.y() + H[8];
  if (w_out) *w_out = w;
  return Vec2(x / w, y / w);
}

// Twice the smallest singular value of the centred points' spread, over the largest: 0 when
// they lie on a line.
double flatness(const std::vector<Vec2>& pts) {
  Vec2 c = Vec2::Zero();
  for (const Vec2& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  Mat2 S = Mat2::Zero();
  for (const Vec2& p : pts) S += (p - c) * (p - c).transpose();
  Eigen::SelfAdjointEigenSolver<Mat2> es(S);
  const double lo = std::max(0.0, es.eigenvalues()(0)), hi = es.eigenvalues()(1);
  return hi > 0 ? std::sqrt(lo / hi) : 0;
}

// Whether three of the points lie on one line (within a relative tolerance).
bool three_collinear(const std::vector<Vec2>& p, size_t& a, size_t& b, size_t& c) {
  double extent = 0;
  for (size_t i = 0; i < p.size(); ++i)
    for (size_t j = i + 1; j < p.size(); ++j) extent = std::max(extent, (p[i] - p[j]).norm());
  for (a = 0; a < p.size(); ++a)
    for (b = a + 1; b < p.size(); ++b)
      for (c = b + 1; c < p.size(); ++c) {
        const Vec2 u = p[b] - p[a], v = p[c] - p[a];
        if (std::abs(u.x() * v.y() - u.y() * v.x()) <= 1e-6 * extent * extent) return true;
      }
  return false;
}

std::string point_text(const Vec2& p) { return "(" + format_number(p.x()) + ", " + format_number(p.y()) + ")"; }

}  // namespace

void Calibration::finish(const std::string& where) {
  for (double h : H_)
    if (!std::isfinite(h)) throw Error(where + ": the homography is not finite (degenerate points)");
  const double det = cv::determinant(cv::Matx33d(H_.data()));
  double norm = 0;
  for (double h : H_) norm = std::max(norm, std::abs(h));
  if (!(std::abs(det) > 1e-12 * norm * norm * norm))
    throw Error(where + ": the homography is degenerate (determinant " + format_number(det) +
                "): it maps the image onto a line or a point");
  Hinv_ = invert(H_);
}

Calibration Calibration::from_homography(const std::array<double, 9>& H, const std::string& where) {
  Calibration c;
  c.homography_ = true;
  c.H_ = H;
  c.finish(where);
  // The ground side: where the image centre region maps with w of the sign at the origin pixel.
  double w = 0;
  apply(c.H_, Vec2(0, 0), &w);
  c.sign_ = w >= 0 ? 1 : -1;
  return c;
}

Calibration Calibration::from_points(const std::vector<Vec2>& image, const std::vector<Vec2>& world,
                                     const std::string& where) {
  if (image.size() != world.size())
    throw Error(where + ": " + std::to_string(image.size()) + " image points but " + std::to_string(world.size()) +
                " world points; they must come in pairs");
  if (image.size() < 4)
    throw Error(where + ": a homography needs at least 4 image <-> world point pairs, got " + std::to_string(image.size()));
  for (size_t i = 0; i < image.size(); ++i)
    if (!image[i].allFinite() || !world[i].allFinite())
      throw Error(where + ": point pair " + std::to_string(i) + " is not finite");
  for (const auto* pts : {&image, &world}) {
    const char* which = pts == &image ? "image" : "world";
    if (flatness(*pts) < 1e-6) throw Error(where + ": the " + std::string(which) + " points all lie on one line; a homography needs them spread over an area");
    size_t a, b, c;
    if (pts->size() == 4 && three_collinear(*pts, a, b, c))
      throw Error(where + ": " + which + " points " + std::to_string(a) + ", " + std::to_string(b) + " and " +
                  std::to_string(c) + " lie on one line; with four pairs no three may");
  }
  std::vector<cv::Point2d> src, dst;
  for (size_t i = 0; i < image.size(); ++i) {
    src.emplace_back(image[i].x(), image[i].y());
    dst.emplace_back(world[i].x(), world[i].y());
  }
  cv::Mat H = cv::findHomography(src, dst, 0);
  if (H.empty()) throw Error(where + ": no homography fits these point pairs (degenerate configuration)");
  std::array<double, 9> h;
  for (int i = 0; i < 9; ++i) h[static_cast<size_t>(i)] = H.at<double>(i / 3, i % 3);
  Calibration c;
  c.homography_ = true;
  c.H_ = h;
  c.finish(where);
  // Every calibration point must be on one side of the horizon.
  double w0 = 0;
  apply(c.H_, image[0], &w0);
  c.sign_ = w0 >= 0 ? 1 : -1;
  double extent = 0, err = 0;
  for (size_t i = 0; i < image.size(); ++i) {
    double w = 0;
    const Vec2 g = apply(c.H_, image[i], &w);
    if (!(w * c.sign_ > 0))
      throw Error(where + ": image point " + std::to_string(i) + " " + point_text(image[i]) +
                  " falls beyond the horizon of the fitted homography; the pairs are inconsistent");
    err += (g - world[i]).norm();
    for (size_t j = 0; j < world.size(); ++j) extent = std::max(extent, (world[i] - world[j]).norm());
  }
  c.reprojection_ = err / static_cast<double>(image.size());
  if (!(c.reprojection_ <= 0.05 * extent))
    throw Error(where + ": the homography reproduces the world points only to " + format_number(c.reprojection_) +
                " m on average (" + format_number(100 * c.reprojection_ / extent) +
                "% of their extent); check that the pairs match and lie on the ground plane");
  return c;
}

Calibration Calibration::from_scale(double s, const Vec2& origin, const std::string& where) {
  if (!(std::isfinite(s) && s > 0 && s < 100)) throw Error(where + ": scale must be metres per pixel in (0, 100), got " + format_number(s));
  if (!origin.allFinite()) throw Error(where + ": origin must be finite");
  Calibration c;
  c.scale_ = s;
  c.H_ = {s, 0, -s * origin.x(), 0, -s, s * origin.y(), 0, 0, 1};
  c.finish(where);
  c.sign_ = 1;
  return c;
}

Calibration Calibration::from_json(const JsonReader& r, double image_height) {
  r.require_object();
  if (r.string("format", std::nullopt) != "crowdmpm-calibration") r.fail_at("format", "must be \"crowdmpm-calibration\"");
  const int version = r.integer("version", 1, 1000, std::nullopt);
  if (version != 1) r.fail_at("version", "unsupported calibration version " + std::to_string(version) + " (this engine reads 1)");
  if (r.has("scale")) {
    r.allow_only({"format", "version", "scale", "origin", "description"});
    return from_scale(r.positive("scale", std::nullopt), r.vec2("origin", Vec2(0, image_height)), r.path());
  }
  r.allow_only({"format", "version", "image_points", "world_points", "description"});
  if (!r.has("image_points") || !r.has("world_points"))
    r.fail("needs \"image_points\" and \"world_points\" (four or more pairs) or a \"scale\" (metres per pixel)");
  const std::vector<Vec2> img = r.at("image_points").as_points(0), wld = r.at("world_points").as_points(0);
  return from_points(img, wld, r.path());
}

Calibration Calibration::load(const std::string& path, double image_height, const InputPolicy& policy) {
  const json j = load_json_file(path, policy);
  return from_json(JsonReader(j, path), image_height);
}

Vec2 Calibration::to_world(const Vec2& pixel) const {
  double w = 0;
  const Vec2 g = apply(H_, pixel, &w);
  if (!(w * sign_ > 0)) return Vec2(std::nan(""), std::nan(""));
  return g;
}

Vec2 Calibration::to_image(const Vec2& world) const { return apply(Hinv_, world); }

double Calibration::pixel_area(const Vec2& p) const {
  double w = 0;
  apply(H_, p, &w);
  if (!(w * sign_ > 0)) return std::nan("");
  // d(world)/d(pixel) of x = (a u + b v + c) / w: (row_i - world_i * row_w) / w.
  const Vec2 g = apply(H_, p);
  const double j00 = (H_[0] - g.x() * H_[6]) / w, j01 = (H_[1] - g.x() * H_[7]) / w;
  const double j10 = (H_[3] - g.y() * H_[6]) / w, j11 = (H_[4] - g.y() * H_[7]) / w;
  return std::abs(j00 * j11 - j01 * j10);
}

void Calibration::check_region(const std::vector<Vec2>& region, const std::string& what) const {
  for (const Vec2& p : region) {
    double w = 0;
    apply(H_, p, &w);
    if (!(w * sign_ > 1e-9 * std::abs(H_[8])))
      throw Error(what + ": pixel " + point_text(p) +
                  " lies on or beyond the horizon of the calibration (the ground plane does not reach it); "
                  "restrict the region of interest to the ground");
  }
}

json Calibration::to_json(std::vector<Vec2> world) const {
  json j{{"format", "crowdmpm-calibration"}, {"version", 1}};
  if (!homography_) {
    j["scale"] = scale_;
    j["origin"] = {-H_[2] / scale_, H_[5] / scale_};
    return j;
  }
  if (world.empty()) world = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
  json img = json::array(), wld = json::array();
  for (const Vec2& g : world) {
    const Vec2 p = to_image(g);
    img.push_back({p.x(), p.y()});
    wld.push_back({g.x(), g.y()});
  }
  j["image_points"] = img;
  j["world_points"] = wld;
  return j;
}

}  // namespace crowdmpm
