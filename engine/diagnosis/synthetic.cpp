#include "engine/diagnosis/synthetic.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>

namespace crowdmpm {

void write_noisy_recording(const ScenarioDef& truth, const Model& model, double noise, uint64_t seed, int threads,
                           const std::string& path) {
  if (!(noise >= 0 && std::isfinite(noise))) throw Error("recording noise must be a finite sd >= 0 m");
  Simulation sim(truth, model, threads);
  const long per_frame = truth.steps_per_frame();
  std::ofstream f(path);
  if (!f) throw Error(path + ": cannot write");
  f << "# framerate: " << truth.output_rate << "\n# unit: m\n# " << truth.name << " run by " << material_name(model.material)
    << " (" << model.name << "), tracking noise " << noise << " m\n";
  Rng rng(seed);
  char line[128];
  for (long frame = 0;; ++frame) {
    const World& w = sim.world();
    for (size_t p = 0; p < w.size(); ++p) {
      const double x = w.x[p].x() + noise * rng.normal();
      const double y = w.x[p].y() + noise * rng.normal();
      std::snprintf(line, sizeof line, "%llu %ld %.4f %.4f\n", static_cast<unsigned long long>(w.id[p]), frame, x, y);
      f << line;
    }
    if (sim.finished()) break;
    sim.run_steps(per_frame);
  }
  f.close();
  if (!f) throw Error(path + ": cannot write");
}

}  // namespace crowdmpm
