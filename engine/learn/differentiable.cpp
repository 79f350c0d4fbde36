#include "engine/learn/differentiable.hpp"

namespace crowdmpm {

namespace {
// A step's input state, and what its drive and traction produced (so that the backward pass
// does not run them again).
struct Stored {
  std::vector<Vec2> x, v, heading;  // heading before the step (the drive's fallback)
  std::vector<Mat2> C;
  std::vector<double> J;
  std::vector<Vec2> accel, force, heading_used;
};

Stored store(const World& w) { return Stored{w.x, w.v, w.heading, w.C, w.J, {}, {}, {}}; }

// The state a step starts from (x, v, C, J) with the given heading.
void restore_state(World& w, const Stored& s, const std::vector<Vec2>& heading) {
  w.x = s.x;
  w.v = s.v;
  w.C = s.C;
  w.J = s.J;
  w.heading = heading;
}

// Into the simulation's own world (checkpoints, the window's end): the heading before the step.
void restore_state(World& w, const Stored& s) { restore_state(w, s, s.heading); }

// Into the backward pass's scratch world: also what the step's drive and traction produced.
void restore(World& w, const Stored& s) {
  restore_state(w, s, s.heading_used);
  w.accel = s.accel;
  w.pair_force = s.force;
}

// Central-difference Jacobian of a pointwise map R^4 -> R^4 (the projection, the drive): these
// are small local functions (DESIGN.md section 4 allows local Jacobians computed on their own).
template <class F>
Eigen::Matrix4d local_jacobian(F&& f, const Eigen::Vector4d& at) {
  const double h = 1e-7;
  Eigen::Matrix4d J;
  for (int k = 0; k < 4; ++k) {
    Eigen::Vector4d up = at, down = at;
    up[k] += h;
    down[k] -= h;
    J.col(k) = (f(up) - f(down)) / (2 * h);
  }
  return J;
}
}  // namespace

ModelGradient WindowGradient::run(Simulation& sim, int steps, const StateLossGrad& loss_grad) {
  const Model& model = sim.model();
  if (model.material == MaterialKind::Elastic || !model.is_continuum())
    throw Error(std::string("gradients through the simulator cover the crowd and fluid materials, not ") + material_name(model.material));
  const size_t n = sim.world().size();
  const std::vector<EntityId> ids = sim.world().id;
  // Segments of K steps: without checkpointing one segment whose states the forward pass keeps;
  // with it, only each segment's first state is kept and the backward pass runs the segment
  // forward again (one more forward pass in all) to get its states back.
  const int K = checkpoint_every_ > 0 && checkpoint_every_ < steps ? checkpoint_every_ : std::max(steps, 1);
  const bool checkpointing = K < steps;
  std::vector<Stored> states, checkpoints;
  std::vector<Simulation::Clock> checkpoint_clocks;
  std::vector<std::vector<Vec2>> loss_x(static_cast<size_t>(steps) + 1), loss_v(static_cast<size_t>(steps) + 1);
  auto step_and_record = [&](std::vector<Stored>& into) {
    into.push_back(store(sim.world()));
    sim.step();
    // The drive and traction of this step are still in the world's arrays (agents fixed).
    into.back().accel = sim.world().accel;
    into.back().force = sim.world().pair_force;
    into.back().heading_used = sim.world().heading;
  };
  peak_stored_steps_ = 0;
  if (!checkpointing) states.reserve(static_cast<size_t>(steps));
  for (int k = 0; k < steps; ++k) {
    if (checkpointing) {
      if (k % K == 0) {
        checkpoints.push_back(store(sim.world()));
        checkpoint_clocks.push_back(sim.clock());
      }
      sim.step();
    } else {
      step_and_record(states);
    }
    if (sim.world().size() != n || sim.world().id != ids)
      throw Error("an agent entered or left the world during the gradient window (step " + std::to_string(k + 1) +
                  "); gradients need a fixed set of agents");
    std::vector<Vec2> gx(n, Vec2::Zero()), gv(n, Vec2::Zero());
    if (loss_grad(k + 1, sim.world(), gx, gv)) {
      loss_x[static_cast<size_t>(k) + 1] = std::move(gx);
      loss_v[static_cast<size_t>(k) + 1] = std::move(gv);
    }
  }
  const Stored final_state = checkpointing ? store(sim.world()) : Stored{};
  const Simulation::Clock final_clock = sim.clock();
  ModelGradient out;
  out.network.assign(model.traction.parameter_count(), 0);
  std::vector<Vec2> xb(n, Vec2::Zero()), vb(n, Vec2::Zero());
  std::vector<Mat2> Cb(n, Mat2::Zero());
  std::vector<double> Jb(n, 0);
  // A scratch world with the agents' fixed components, and the simulation's inputs.
  World w = sim.world();
  const ScenarioDef& sc = sim.scenario();
  const std::vector<Behaviour>& behaviours = sim.behaviours();
  StepInputs in = sim.step_inputs();
  ThreadPool pool(1);
  NeighbourGrid nb = sim.neighbour_grid();
  Grid grid = sim.grid();
  TractionAdjoint tadj;
  TransferAdjoint xadj;
  const MaterialParams& P = model.params;
  for (int k = steps - 1; k >= 0; --k) {
    if (checkpointing && (k == steps - 1 || k % K == K - 1)) {
      // Entering segment k / K from its end: run it forward again from its checkpoint.
      const int seg = k / K;
      World& sw = sim.world();
      restore_state(sw, checkpoints[static_cast<size_t>(seg)]);
      sim.set_clock(checkpoint_clocks[static_cast<size_t>(seg)]);
      states.clear();
      for (int j = seg * K; j <= k; ++j) {
        step_and_record(states);
        if (sw.size() != n || sw.id != ids)
          throw Error("an agent entered or left the world while the gradient window was run again from a checkpoint (step " +
                      std::to_string(j + 1) + ")");
      }
    }
    peak_stored_steps_ = std::max(peak_stored_steps_, states.size() + checkpoints.size());
    const Stored& st = states[static_cast<size_t>(checkpointing ? k % K : k)];
    if (!loss_x[static_cast<size_t>(k) + 1].empty())
      for (size_t p = 0; p < n; ++p) {
        xb[p] += loss_x[static_cast<size_t>(k) + 1][p];
        vb[p] += loss_v[static_cast<size_t>(k) + 1][p];
      }
    // Step k's state with its stored drive and traction; neighbour lists are rebuilt, the
    // transfer adjoint recomputes the grid.
    restore(w, st);
    nb.build(w, pool);
    // Transfer adjoint, with the projection's adjoint applied per particle at the state after
    // G2P (a local Jacobian of (x, v) -> (x', v') where the projection acts; identity elsewhere).
    struct HookCtx {
      const StepInputs* in;
      const Geometry* geo;
      double clearance;
    } ctx{&in, &sc.geo, P.wall_clearance};
    auto hook = [](void* c, size_t, const Vec2& xa, const Vec2& va, Vec2& xbar, Vec2& vbar) {
      const HookCtx& h = *static_cast<const HookCtx*>(c);
      if (h.geo->sdf(xa) >= h.clearance + 1e-6) return;
      auto proj = [&](const Eigen::Vector4d& s4) {
        Vec2 x(s4[0], s4[1]), v(s4[2], s4[3]);
        project_point(*h.in, x, v);
        return Eigen::Vector4d(x.x(), x.y(), v.x(), v.y());
      };
      Eigen::Matrix4d Jm = local_jacobian(proj, Eigen::Vector4d(xa.x(), xa.y(), va.x(), va.y()));
      Eigen::Vector4d g = Jm.transpose() * Eigen::Vector4d(xbar.x(), xbar.y(), vbar.x(), vbar.y());
      xbar = Vec2(g[0], g[1]);
      vbar = Vec2(g[2], g[3]);
    };
    xadj.reset(n);
    kernel_transfer_adjoint(in, grid, w, xb, vb, Cb, Jb, xadj, hook, &ctx);
    out.E += xadj.E;
    out.gamma += xadj.gamma;
    out.tension_scale += xadj.tension_scale;
    out.alignment_time += xadj.alignment_time;
    // Traction adjoint.
    tadj.reset(n, out.network.size());
    kernel_traction_adjoint(in, nb, w, xadj.force, tadj);
    for (size_t i = 0; i < out.network.size(); ++i) out.network[i] += tadj.network[i];
    // Drive adjoint: accel and heading as local functions of (x, v); tau and v0_scale exactly.
    for (size_t p = 0; p < n; ++p) {
      const Behaviour& beh = behaviours[static_cast<size_t>(w.behaviour[p])];
      const Vec2 hb = tadj.heading[p];
      const Vec2 ab = xadj.accel[p];
      // Acceleration and heading as functions of x (local central differences: the navigation
      // field and the behaviours are pointwise); the acceleration's v-dependence is exact.
      auto drive_x = [&](const Vec2& x) {
        Vec2 a, h;
        drive_point(in, beh, w.group[p], x, w.v[p], w.v0[p], st.heading[p], a, h);
        return std::make_pair(a, h);
      };
      Vec2 gx = Vec2::Zero();
      const double hx = 1e-7;
      for (int c = 0; c < 2; ++c) {
        Vec2 up = w.x[p], dn = w.x[p];
        up[c] += hx;
        dn[c] -= hx;
        auto [au, hu] = drive_x(up);
        auto [ad, hd] = drive_x(dn);
        gx[c] = (ab.dot(au - ad) + hb.dot(hu - hd)) / (2 * hx);
      }
      Vec2 gv = Vec2::Zero();
      if (beh.kind != Behaviour::Kind::None) gv -= ab / P.tau;  // a = (s v0 e - v) / tau
      if (hb.squaredNorm() > 0 && desired_direction(in, beh, w.x[p]).squaredNorm() == 0 && w.v[p].squaredNorm() > 1e-8) {
        // Heading = v / |v| when there is no desired direction.
        const Vec2 u = w.v[p].normalized();
        gv += (hb - hb.dot(u) * u) / w.v[p].norm();
      }
      xb[p] = xadj.x[p] + tadj.x[p] + gx;
      vb[p] = xadj.v[p] + tadj.v[p] + gv;
      if (beh.kind != Behaviour::Kind::None) {
        // a_drive = (s v0 e - v) / tau with e the desired direction; body forces do not depend
        // on tau or on s = v0_scale.
        const Vec2 e = desired_direction(in, beh, w.x[p]);
        const Vec2 a_drive = (P.v0_scale * w.v0[p] * e - w.v[p]) / P.tau;
        out.tau += ab.dot(-a_drive / P.tau);
        out.v0_scale += ab.dot(w.v0[p] * e / P.tau);
      }
      out.comfort_distance += tadj.comfort[p];
      Cb[p] = xadj.C[p];
      Jb[p] = xadj.J[p];
    }
  }
  if (checkpointing) {  // leave the simulation at the end of the window, as without checkpoints
    sim.set_clock(final_clock);
    restore_state(sim.world(), final_state);
  }
  out.x0 = xb;
  out.v0 = vb;
  return out;
}

}  // namespace crowdmpm
