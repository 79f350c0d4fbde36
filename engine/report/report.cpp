#include "engine/report/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "engine/core/error.hpp"
#include "engine/core/json_reader.hpp"
#include "engine/io/jupedsim_sqlite.hpp"
#include "engine/io/render.hpp"
#include "engine/observe/pedestrian_measures.hpp"
#include "engine/sim/scenario.hpp"

namespace crowdmpm {

namespace fs = std::filesystem;

namespace {

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += k[v >> 18], out += k[(v >> 12) & 63], out += k[(v >> 6) & 63], out += k[v & 63];
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    out += k[v >> 18], out += k[(v >> 12) & 63], out += "==";
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8);
    out += k[v >> 18], out += k[(v >> 12) & 63], out += k[(v >> 6) & 63], out += '=';
  }
  return out;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot read");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string num(double v, int digits = 3) {
  if (!std::isfinite(v)) return "–";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// A round tick step for a span.
double tick_step(double span) {
  if (!(span > 0)) return 1;
  const double raw = span / 5, base = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * base >= raw) return m * base;
  return 10 * base;
}

struct Series {
  std::string name;
  std::vector<std::pair<double, double>> xy;
};

// An inline SVG line chart with axes, ticks and a legend.
std::string svg_chart(const std::string& title, const std::string& xlabel, const std::string& ylabel,
                      const std::vector<Series>& series) {
  static const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  const double W = 640, H = 300, L = 60, R = 150, T = 30, B = 45;
  double x0 = 1e300, x1 = -1e300, y0 = 0, y1 = -1e300;
  for (const auto& s : series)
    for (const auto& [x, y] : s.xy)
      if (std::isfinite(x) && std::isfinite(y)) x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H << "\" viewBox=\"0 0 " << W << " " << H
    << "\" role=\"img\" aria-label=\"" << html_escape(title) << "\"><rect width=\"100%\" height=\"100%\" fill=\"white\"/>"
    << "<text x=\"" << L << "\" y=\"18\" font-size=\"14\" font-family=\"sans-serif\">" << html_escape(title) << "</text>";
  if (!(x1 > x0)) {
    o << "<text x=\"" << L << "\" y=\"" << H / 2 << "\" font-family=\"sans-serif\">no data</text></svg>";
    return o.str();
  }
  if (!(y1 > y0)) y1 = y0 + 1;
  const double sx = (W - L - R) / (x1 - x0), sy = (H - T - B) / (y1 - y0);
  auto X = [&](double x) { return L + (x - x0) * sx; };
  auto Y = [&](double y) { return H - B - (y - y0) * sy; };
  o << "<g font-family=\"sans-serif\" font-size=\"11\" stroke-width=\"1\">";
  const double xs = tick_step(x1 - x0), ys = tick_step(y1 - y0);
  for (double x = std::ceil(x0 / xs) * xs; x <= x1 + 1e-9 * xs; x += xs)
    o << "<line x1=\"" << X(x) << "\" y1=\"" << T << "\" x2=\"" << X(x) << "\" y2=\"" << H - B << "\" stroke=\"#eee\"/><text x=\""
      << X(x) << "\" y=\"" << H - B + 15 << "\" text-anchor=\"middle\">" << num(x, 4) << "</text>";
  for (double y = std::ceil(y0 / ys) * ys; y <= y1 + 1e-9 * ys; y += ys)
    o << "<line x1=\"" << L << "\" y1=\"" << Y(y) << "\" x2=\"" << W - R << "\" y2=\"" << Y(y) << "\" stroke=\"#eee\"/><text x=\""
      << L - 6 << "\" y=\"" << Y(y) + 4 << "\" text-anchor=\"end\">" << num(y, 4) << "</text>";
  o << "<rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W - L - R << "\" height=\"" << H - T - B
    << "\" fill=\"none\" stroke=\"black\"/>";
  o << "<text x=\"" << (L + W - R) / 2 << "\" y=\"" << H - 8 << "\" text-anchor=\"middle\">" << html_escape(xlabel) << "</text>";
  o << "<text transform=\"translate(14," << (T + H - B) / 2 << ") rotate(-90)\" text-anchor=\"middle\">" << html_escape(ylabel)
    << "</text>";
  for (size_t k = 0; k < series.size(); ++k) {
    const char* c = colours[k % 8];
    const double row = 16.0 * static_cast<double>(k);
    o << "<polyline fill=\"none\" stroke=\"" << c << "\" stroke-width=\"1.5\" points=\"";
    // At most ~1500 points per line: enough for the eye, small pages.
    const size_t stride = std::max<size_t>(1, series[k].xy.size() / 1500);
    for (size_t i = 0; i < series[k].xy.size(); i += stride) {
      const auto& [x, y] = series[k].xy[i];
      if (std::isfinite(x) && std::isfinite(y)) o << num(X(x), 6) << "," << num(Y(y), 6) << " ";
    }
    o << "\"/><line x1=\"" << W - R + 10 << "\" y1=\"" << T + 8 + row << "\" x2=\"" << W - R + 28 << "\" y2=\"" << T + 8 + row
      << "\" stroke=\"" << c << "\" stroke-width=\"2\"/><text x=\"" << W - R + 32 << "\" y=\"" << T + 12 + row << "\">"
      << html_escape(series[k].name) << "</text>";
  }
  o << "</g></svg>";
  return o.str();
}

std::vector<std::pair<double, double>> pairs(const json& a, size_t xi, size_t yi) {
  std::vector<std::pair<double, double>> out;
  for (const auto& r : a)
    if (r.is_array() && r.size() > std::max(xi, yi) && r[xi].is_number() && r[yi].is_number())
      out.emplace_back(r[xi].get<double>(), r[yi].get<double>());
  return out;
}

}  // namespace

std::string write_report(const std::string& dir, const ReportOptions& opt) {
  const fs::path d(dir);
  if (!fs::is_directory(d)) throw Error(dir + ": not a folder (give the --out folder of crowdmpm simulate)");
  const std::string metrics_path = (d / "metrics.json").string();
  if (!fs::exists(metrics_path)) throw Error(dir + ": no metrics.json (run crowdmpm simulate SCENARIO --out " + dir + " first)");
  const json m = load_json_file(metrics_path, opt.input);
  JsonReader r(m, metrics_path);
  const std::string name = r.string("scenario", std::string("scenario"));
  std::vector<std::string> notes;  // what could not be shown, and why

  // The venue, for the crowd-pressure map.
  std::string scenario_path = opt.scenario;
  if (scenario_path.empty() && m.contains("scenario_file") && m["scenario_file"].is_string())
    scenario_path = m["scenario_file"].get<std::string>();
  std::optional<ScenarioDef> scenario;
  if (!scenario_path.empty()) {
    try {
      InputPolicy own = opt.input;
      own.allow_outside_paths = true;  // the scenario the user ran, named by the run itself
      scenario = ScenarioDef::load(scenario_path, own);
    } catch (const Error& e) {
      if (!opt.scenario.empty()) throw;
      notes.push_back(std::string("the scenario could not be read, maps show no walls: ") + e.what());
    }
  }

  // Crowd pressure (Helbing) from the trajectories: the window with the highest peak.
  std::string pressure_png, pressure_text;
  const fs::path traj_sqlite = d / "trajectories.sqlite", traj_txt = d / "trajectories.txt";
  // The newer of the two (a run with trajectories_sqlite off leaves an older .sqlite behind).
  std::string traj;
  for (const fs::path& p : {traj_sqlite, traj_txt})
    if (fs::exists(p) && (traj.empty() || fs::last_write_time(p) > fs::last_write_time(traj))) traj = p.string();
  if (traj.empty()) {
    notes.push_back("no trajectories.sqlite or trajectories.txt: no crowd-pressure map");
  } else {
    try {
      const TrajectorySet t = TrajectorySet::read(traj, 0, opt.input);
      const long n = std::max(1L, std::lround(0.5 * t.framerate));
      const std::vector<Vec2> v = individual_velocities(t, n);
      auto [lo, hi] = t.bounds();
      if (scenario) lo = scenario->geo.lo, hi = scenario->geo.hi;
      const long window = std::max(2L, std::lround(opt.pressure_window * t.framerate));
      const PressurePeak peak = peak_crowd_pressure(t, v, window, lo, hi, 0.25, opt.pressure_radius);
      const PressureField& best = peak.field;
      if (best.pressure.empty()) {
        notes.push_back(traj + ": nobody in any window: no crowd-pressure map");
      } else {
        const FieldFrame ff = best.grid();
        Geometry geo;
        if (scenario) geo = scenario->geo;
        else geo.lo = lo, geo.hi = hi;
        pressure_png = (d / "crowd_pressure.png").string();
        const double top = std::max(0.04, best.max_pressure());
        const double from = static_cast<double>(peak.from) / t.framerate, to = static_cast<double>(peak.to) / t.framerate;
        write_field_png(pressure_png, geo, View::fit(geo, scenario ? scenario->outputs.pixels_per_metre : 0), ff,
                        best.pressure, 0, top, name + ": crowd pressure, " + num(from) + "-" + num(to) + " s", "1/s2");
        pressure_text = "Peak crowd pressure " + num(best.max_pressure()) + " s⁻² in the window from " + num(from) +
                        " s (Helbing et al. 2007: density × variance of the local velocity, R = " + num(opt.pressure_radius) +
                        " m; crowd turbulence sets in near 0.02 s⁻²" +
                        (best.max_pressure() > 0.02 ? ", exceeded here" : ", not reached here") + ").";
      }
    } catch (const Error& e) {
      pressure_png.clear();
      notes.push_back(std::string("no crowd-pressure map: ") + e.what());
    }
  }

  // The video, re-encoded for browsers and inlined.
  std::string video_b64;
  const fs::path mp4 = d / "particles.mp4";
  if (fs::exists(mp4)) {
    const auto [frames, fps] = video_frame_count(mp4.string());
    (void)fps;
    const int stride = static_cast<int>(std::max(1L, (frames + opt.video_max_frames - 1) / std::max(1, opt.video_max_frames)));
    // Re-encoded in the temporary folder: the run folder may be read-only.
    std::random_device rd;
    const fs::path webm = fs::temp_directory_path() / ("crowdmpm_report_" + std::to_string(rd()) + "_" + std::to_string(rd()) + ".webm");
    try {
      transcode_to_webm(mp4.string(), webm.string(), stride, opt.video_scale);
      video_b64 = base64(read_bytes(webm.string()));
    } catch (const Error& e) {
      notes.push_back(std::string("no video: ") + e.what());
    }
    std::error_code ec;
    fs::remove(webm, ec);
  } else {
    notes.push_back("no particles.mp4: no video");
  }

  // Charts.
  std::vector<Series> nt, remaining, area_density, area_pressure;
  if (m.contains("exits"))
    for (const auto& e : m["exits"]) nt.push_back({e.value("id", std::string("exit")), pairs(e.value("N", json::array()), 0, 1)});
  remaining.push_back({"agents in the venue", pairs(m.value("agents_remaining", json::array()), 0, 1)});
  if (m.contains("measurement_areas"))
    for (const auto& a : m["measurement_areas"]) {
      const std::string id = a.value("id", std::string("area"));
      area_density.push_back({id, pairs(a.value("series", json::array()), 0, 1)});
      area_pressure.push_back({id, pairs(a.value("series", json::array()), 0, 2)});
    }

  auto img = [&](const std::string& file, const std::string& caption) -> std::string {
    const fs::path p = d / file;
    if (!fs::exists(p)) {
      notes.push_back(file + " is missing");
      return "";
    }
    return "<figure><img alt=\"" + html_escape(caption) + "\" src=\"data:image/png;base64," + base64(read_bytes(p.string())) +
           "\"><figcaption>" + html_escape(caption) + "</figcaption></figure>\n";
  };

  std::ostringstream h;
  const double evac = m.contains("evacuation_time") && m["evacuation_time"].is_number() ? m["evacuation_time"].get<double>() : NAN;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>CrowdMPM report: " << html_escape(name)
    << "</title>\n<style>body{font-family:sans-serif;margin:24px;max-width:1400px;color:#222}"
       "h1{font-size:22px}h2{font-size:17px;margin-top:28px;border-bottom:1px solid #ccc}"
       "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:4px 8px;text-align:left}"
       ".grid{display:flex;flex-wrap:wrap;gap:16px}figure{margin:0}img{max-width:660px;height:auto}"
       "figcaption{font-size:13px;color:#555}.note{color:#a33}</style></head>\n<body>\n";
  h << "<h1>CrowdMPM run: " << html_escape(name) << "</h1>\n";
  h << "<table id=\"summary\"><tr><th>simulated time</th><td>" << num(r.number("simulated_time", 0.0), 4) << " s</td></tr>"
    << "<tr><th>people spawned / left / still inside</th><td>" << r.number("agents_spawned", 0.0) << " / "
    << r.number("agents_exited", 0.0) << " / " << r.number("agents_remaining_final", 0.0) << "</td></tr>"
    << "<tr><th>evacuation time</th><td>" << (std::isfinite(evac) ? num(evac, 4) + " s" : "not complete") << "</td></tr>";
  for (const char* k : {"peak_density", "peak_pressure"})
    if (m.contains(k) && m[k].is_object())
      h << "<tr><th>" << (std::string(k) == "peak_density" ? "peak density (persons/m²)" : "peak pressure (model units)")
        << "</th><td>" << num(m[k].value("value", 0.0)) << " at (" << num(m[k].value("x", 0.0)) << ", " << num(m[k].value("y", 0.0))
        << ") m, t = " << num(m[k].value("time", 0.0), 4) << " s</td></tr>";
  if (m.contains("exits"))
    for (const auto& e : m["exits"])
      h << "<tr><th>exit " << html_escape(e.value("id", std::string())) << "</th><td>" << e.value("count", 0L) << " people"
        << (e.contains("flow_rate") && e["flow_rate"].is_number() ? ", " + num(e["flow_rate"].get<double>()) + " persons/s" : "")
        << "</td></tr>";
  if (m.contains("measurement_areas"))
    for (const auto& a : m["measurement_areas"])
      h << "<tr><th>area " << html_escape(a.value("id", std::string())) << "</th><td>mean density " << num(a.value("mean_density", 0.0))
        << " persons/m² (Fruin level " << fruin_level(std::max(0.0, a.value("mean_density", 0.0))) << "), mean pressure "
        << num(a.value("mean_pressure", 0.0)) << "</td></tr>";
  h << "</table>\n";
  h << "<h2>People leaving</h2><div class=\"grid\">" << svg_chart("N(t): people through each exit", "time (s)", "people", nt)
    << svg_chart("People in the venue", "time (s)", "people", remaining) << "</div>\n";
  if (!area_density.empty())
    h << "<h2>Measurement areas</h2><div class=\"grid\">"
      << svg_chart("Density in each area", "time (s)", "persons/m²", area_density)
      << svg_chart("Mean pressure in each area", "time (s)", "model units", area_pressure) << "</div>\n";
  h << "<h2>Maps</h2><div class=\"grid\">" << img("density_mean.png", "Time-averaged density")
    << img("pressure_mean.png", "Time-averaged pressure") << img("pressure_peak.png", "Peak pressure over time")
    << img("level_of_service.png", "Fruin level of service at each place's peak density (walkways: A ≥ 3.25 m² per person … F < 0.46)")
    << (pressure_png.empty() ? "" : img("crowd_pressure.png", pressure_text)) << img("peak.png", "The crowd at peak density")
    << img("final.png", "The crowd at the end") << "</div>\n";
  if (!video_b64.empty())
    h << "<h2>Video</h2><video id=\"run-video\" controls muted width=\"660\" src=\"data:video/webm;base64," << video_b64
      << "\"></video>\n";
  if (!notes.empty()) {
    h << "<h2>Not shown</h2><ul>";
    for (const auto& n : notes) h << "<li class=\"note\">" << html_escape(n) << "</li>";
    h << "</ul>\n";
  }
  h << "<p style=\"font-size:12px;color:#777\">Written by crowdmpm report from " << html_escape(fs::absolute(d).string())
    << ". Units: metres, seconds, persons/m²; pressure in the model's stress units.</p>\n";
  // Marks the page ready once the video has decoded its first frame (or there is none): the
  // headless-browser test reads it; a video that cannot be decoded is a console error.
  h << "<script>(function(){var v=document.getElementById('run-video');function done(s){document.body.setAttribute('data-report',s);}"
       "if(!v){done('ready');return;}v.addEventListener('loadeddata',function(){done('ready');});"
       "v.addEventListener('error',function(){console.error('crowdmpm report: the video cannot be played');done('video-error');});"
       "})();</script>\n</body></html>\n";
  const std::string out = opt.out.empty() ? (d / "report.html").string() : opt.out;
  std::ofstream f(out, std::ios::binary);
  if (!f) throw Error(out + ": cannot write");
  f << h.str();
  f.close();
  if (!f) throw Error(out + ": write failed (disk full?)");
  return out;
}

}  // namespace crowdmpm
