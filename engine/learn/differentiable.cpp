#include "engine/learn/differentiable.hpp"

#include <algorithm>

namespace crowdmpm {

namespace {
// A step's input state, and what its drive and traction produced (so that the backward pass
// does not run them again).
struct Stored {
  std::vector<Vec2> x, v, heading;  // heading before the step (the drive's fallback)
  std::vector<Mat2> C;
  std::vector<double> J;
  std::vector<Vec2> accel, force, heading_used;
  std::vector<double> free_speed;  // the drive's u (for the headway adaptation's adjoint)
};

Stored store(const World& w) { return Stored{w.x, w.v, w.heading, w.C, w.J, {}, {}, {}, {}}; }

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
  w.free_speed = s.free_speed;
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

// Adjoint of drive_point for agent p of the stored state w (heading_prev: its heading before
// the step): given a_bar = dL/da_p and h_bar = dL/dheading_p, adds dL/dx_p, dL/dv_p and the
// gradients of tau, v0_scale, the material's density-speed law and the force terms' parameters
// (f_own: scratch, one value a term). With e the desired direction, f = f_m prod_t f_t the
// material's and the terms' speed factors and a_t the terms' accelerations:
//   a = (s v0 f e - v) / tau + sum_t a_t;   heading = e (or v / |v| where e = 0).
// The terms' parts are exact (their own vector-Jacobian products); e(x) comes from the
// behaviour's navigation field, a pointwise function whose Jacobian is taken by central
// differences (DESIGN.md section 4 allows local Jacobians of pointwise functions).
void drive_adjoint(const StepInputs& in, const Behaviour& beh, const World& w, size_t p, const Vec2& heading_prev,
                   const std::vector<double>& density, const std::vector<double>& ahead, const Vec2& a_bar,
                   const Vec2& h_bar, double u_bar_later, Vec2& x_bar, Vec2& v_bar, double& density_bar, ModelGradient& out,
                   std::vector<double>& f_own) {
  const MaterialParams& P = in.model.params;
  const Vec2 x = w.x[p], v = w.v[p];
  const TermPoint pt = terms_point(in, w, p, heading_prev, density, ahead);
  const bool driven = beh.kind != Behaviour::Kind::None;
  const Vec2 e = desired_direction(in, beh, x, heading_prev);
  // The speed factors, each term's own and the product of the others'.
  f_own.assign(in.terms.size(), 1.0);
  const double f_material = material_density_factor(P, pt);
  double f = f_material;
  for (size_t t = 0; t < in.terms.size(); ++t) {
    if (!in.terms[t].applies(pt.group)) continue;
    Vec2 unused = Vec2::Zero();
    in.terms[t].law->eval(in.terms[t].params.data(), pt, unused, f_own[t]);
    f *= f_own[t];
  }
  const double speed = P.v0_scale * w.v0[p];
  Vec2 e_bar = h_bar.squaredNorm() > 0 && e.squaredNorm() > 0 ? h_bar : Vec2::Zero();
  double f_bar = 0;
  if (driven) {
    // a = (u e - v) / tau with the free speed u = s v0 f, which the headway adaptation also
    // reads (u_bar_later).
    const Vec2 a_drive = (speed * f * e - v) / P.tau;
    e_bar += a_bar * (speed * f / P.tau);
    const double u_bar = a_bar.dot(e) / P.tau + (e.squaredNorm() > 0 ? u_bar_later : 0.0);
    f_bar = u_bar * speed;
    v_bar -= a_bar / P.tau;
    out.params.tau += a_bar.dot(-a_drive / P.tau);
    out.params.v0_scale += u_bar * w.v0[p] * f;
  }
  if (e_bar.squaredNorm() > 0) {
    const double h = 1e-7;
    for (int c = 0; c < 2; ++c) {
      Vec2 up = x, dn = x;
      up[c] += h;
      dn[c] -= h;
      x_bar[c] += e_bar.dot(desired_direction(in, beh, up, heading_prev) - desired_direction(in, beh, dn, heading_prev)) / (2 * h);
    }
  }
  // (A heading kept from entry is a constant of the window: nothing to propagate.)
  if (beh.kind != Behaviour::Kind::Heading && h_bar.squaredNorm() > 0 && e.squaredNorm() == 0 && v.squaredNorm() > 1e-8) {
    // Heading = v / |v| when there is no desired direction.
    const Vec2 u = v.normalized();
    v_bar += (h_bar - h_bar.dot(u) * u) / v.norm();
  }
  if (f_bar != 0 && material_density_law(P)) {
    double terms_f = 1;
    for (double ft : f_own) terms_f *= ft;
    density_bar = material_density_factor_vjp(P, pt, f_bar * terms_f, out.params);
  }
  for (size_t t = 0; t < in.terms.size(); ++t) {
    const Term& term = in.terms[t];
    if (!term.applies(pt.group)) continue;
    double others = f_material;
    for (size_t u = 0; u < in.terms.size(); ++u)
      if (u != t) others *= f_own[u];
    term.law->vjp(term.params.data(), pt, a_bar, f_bar * others, x_bar, v_bar, out.terms[t].data());
  }
}

// Adjoint of kernel_headway at the stored state w (heading = e, free_speed = u): where the
// speed was capped, a_p += (V - u) e / tau with V = max(0, (s - s0) / T) and
// s = (x_q - x_p) . e - r_p - r_q. Adds dL/dx of p and q, dL/de_p, dL/du_p, and tau's, T's and
// s0's gradients.
void headway_adjoint(const StepInputs& in, const NeighbourGrid& nb, const World& w, const std::vector<Vec2>& a_bar,
                     std::vector<Vec2>& x_bar, std::vector<Vec2>& e_bar, std::vector<double>& u_bar, ModelGradient& out) {
  const MaterialParams& P = in.model.params;
  if (!(P.time_gap > 0)) return;
  for (size_t p = 0; p < w.size(); ++p) {
    const double u = w.free_speed[p];
    if (!(u > 0)) continue;
    const Vec2 e = w.heading[p];
    const Headway h = headway_point(nb, w, p, e, P.headway_width, headway_look(P, u));
    const double V = headway_speed(P, h.gap);
    if (!(V < u)) continue;
    const Vec2& ab = a_bar[p];
    const Vec2 c = (V - u) / P.tau * e;
    e_bar[p] += ab * ((V - u) / P.tau);
    u_bar[p] -= ab.dot(e) / P.tau;
    out.params.tau += ab.dot(-c / P.tau);
    if (V > 0) {  // V = (s - s0) / T
      const double V_bar = ab.dot(e) / P.tau, gap_bar = V_bar / P.time_gap;
      out.params.time_gap += V_bar * (-V / P.time_gap);
      out.params.headway_gap -= gap_bar;
      const Vec2 r = w.x[h.q] - w.x[p];
      x_bar[h.q] += gap_bar * e;
      x_bar[p] -= gap_bar * e;
      e_bar[p] += gap_bar * r;
    }
  }
}
}  // namespace

ModelGradient WindowGradient::run(Simulation& sim, int steps, const StateLossGrad& loss_grad,
                                  const std::function<void(Simulation&)>& after_step) {
  const Model& model = sim.model();
  if (model.material == MaterialKind::Elastic || !model.is_continuum())
    throw Error(std::string("gradients through the simulator cover the crowd and fluid materials, not ") + material_name(model.material));
  std::vector<EntityId> ids = sim.world().id;  // the agents so far, in dense order
  // Routes under congestion stay those of the window's start (no adjoint of the route choice;
  // the steps run again from checkpoints must see the same routes).
  struct HeldRoutes {
    Simulation& s;
    bool was;
    ~HeldRoutes() { s.hold_routes(was); }
  } held{sim, sim.routes_held()};
  sim.hold_routes(true);
  // Segments of K steps: without checkpointing one segment whose states the forward pass keeps;
  // with it, only each segment's first state is kept and the backward pass runs the segment
  // forward again (one more forward pass in all) to get its states back.
  const int K = checkpoint_every_ > 0 && checkpoint_every_ < steps ? checkpoint_every_ : std::max(steps, 1);
  const bool checkpointing = K < steps;
  if (checkpointing && after_step)
    throw Error("a gradient window that adds agents after its steps keeps every state: it cannot use checkpoints (" +
                std::to_string(steps) + " steps, a checkpoint every " + std::to_string(K) + ")");
  // Agents may enter (appended by a source or after_step; with checkpoints not even that) but
  // never leave: the backward pass drops the entered ones' adjoints where they appear.
  auto check_agents = [&](int step, bool again) {
    const World& w = sim.world();
    const char* when = again ? " while the gradient window was run again from a checkpoint" : " during the gradient window";
    if (w.size() < ids.size() || !std::equal(ids.begin(), ids.end(), w.id.begin()))
      throw Error(std::string("an agent left the world") + when + " (step " + std::to_string(step) +
                  "); gradients need every agent to stay (exits inside a window are not covered)");
    if (checkpointing && w.size() != ids.size())
      throw Error(std::string("an agent entered the world") + when + " (step " + std::to_string(step) +
                  "); with gradient checkpoints the set of agents must stay fixed");
    ids = w.id;
  };
  std::vector<Stored> states, checkpoints;
  std::vector<Simulation::Clock> checkpoint_clocks;
  std::vector<std::vector<Vec2>> loss_x(static_cast<size_t>(steps) + 1), loss_v(static_cast<size_t>(steps) + 1);
  auto step_and_record = [&](std::vector<Stored>& into, int step, bool again) {
    into.push_back(store(sim.world()));
    sim.step();
    check_agents(step, again);
    // The drive and traction of this step are still in the world's arrays, for the step's own
    // agents (those a source added at its end come after them).
    const World& w = sim.world();
    Stored& st = into.back();
    const auto m = static_cast<long>(st.x.size());
    st.accel.assign(w.accel.begin(), w.accel.begin() + m);
    st.force.assign(w.pair_force.begin(), w.pair_force.begin() + m);
    st.heading_used.assign(w.heading.begin(), w.heading.begin() + m);
    st.free_speed.assign(w.free_speed.begin(), w.free_speed.begin() + m);
  };
  std::vector<double> step_time;  // the clock at the start of each step (time-dependent terms)
  peak_stored_steps_ = 0;
  if (!checkpointing) states.reserve(static_cast<size_t>(steps));
  for (int k = 0; k < steps; ++k) {
    step_time.push_back(sim.time());
    if (checkpointing) {
      if (k % K == 0) {
        checkpoints.push_back(store(sim.world()));
        checkpoint_clocks.push_back(sim.clock());
      }
      sim.step();
      check_agents(k + 1, false);
    } else {
      step_and_record(states, k + 1, false);
    }
    if (after_step) {
      after_step(sim);
      check_agents(k + 1, false);
    }
    const size_t n = sim.world().size();
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
  for (const Term& t : sim.scenario().terms) out.terms.emplace_back(t.params.size(), 0.0);
  // The adjoint of the state after the step being undone: sized to its agents.
  std::vector<Vec2> xb(ids.size(), Vec2::Zero()), vb(ids.size(), Vec2::Zero());
  std::vector<Mat2> Cb(ids.size(), Mat2::Zero());
  std::vector<double> Jb(ids.size(), 0);
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
  std::vector<Vec2> hx, he;  // the headway adjoint's dL/dx and dL/de
  std::vector<double> hu;    // and its dL/du
  std::vector<double> f_own;  // drive_adjoint's scratch: each term's speed factor
  std::vector<double> density_bar;  // dL/d(density ahead) of each agent, from the material's density-speed law
  // dL/d(heading before step k) through the density ahead: taken on as dL/d(heading after step
  // k - 1) by the drive adjoint of step k - 1 (agents entering during the window keep their entry
  // heading: data, dropped with their other entry state).
  std::vector<Vec2> heading_bar, heading_bar_later;
  const MaterialParams& P = model.params;
  for (int k = steps - 1; k >= 0; --k) {
    if (checkpointing && (k == steps - 1 || k % K == K - 1)) {
      // Entering segment k / K from its end: run it forward again from its checkpoint.
      const int seg = k / K;
      World& sw = sim.world();
      restore_state(sw, checkpoints[static_cast<size_t>(seg)]);
      sim.set_clock(checkpoint_clocks[static_cast<size_t>(seg)]);
      states.clear();
      for (int j = seg * K; j <= k; ++j) step_and_record(states, j + 1, true);
    }
    peak_stored_steps_ = std::max(peak_stored_steps_, states.size() + checkpoints.size());
    const Stored& st = states[static_cast<size_t>(checkpointing ? k % K : k)];
    if (!loss_x[static_cast<size_t>(k) + 1].empty())
      for (size_t p = 0; p < xb.size(); ++p) {
        xb[p] += loss_x[static_cast<size_t>(k) + 1][p];
        vb[p] += loss_v[static_cast<size_t>(k) + 1][p];
      }
    // The agents that entered during step k (or after it) end here: their entry state is data.
    const size_t n = st.x.size();
    xb.resize(n);
    vb.resize(n);
    Cb.resize(n);
    Jb.resize(n);
    while (w.size() > n) w.remove_at(w.size() - 1);
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
    } ctx{&in, &sc.geo, std::max(P.wall_clearance, P.shoulder_clearance)};
    auto hook = [](void* c, size_t, const Vec2& xa, const Vec2& va, Vec2& xbar, Vec2& vbar) {
      const HookCtx& h = *static_cast<const HookCtx*>(c);
      if (h.geo->sdf(xa) >= h.clearance + 1e-6) return;
      const double clearance = projection_clearance(h.in->model.params, *h.geo, xa);
      auto proj = [&](const Eigen::Vector4d& s4) {
        Vec2 x(s4[0], s4[1]), v(s4[2], s4[3]);
        project_point(*h.in, x, v, clearance);
        return Eigen::Vector4d(x.x(), x.y(), v.x(), v.y());
      };
      Eigen::Matrix4d Jm = local_jacobian(proj, Eigen::Vector4d(xa.x(), xa.y(), va.x(), va.y()));
      Eigen::Vector4d g = Jm.transpose() * Eigen::Vector4d(xbar.x(), xbar.y(), vbar.x(), vbar.y());
      xbar = Vec2(g[0], g[1]);
      vbar = Vec2(g[2], g[3]);
    };
    xadj.reset(n);
    kernel_transfer_adjoint(in, grid, w, xb, vb, Cb, Jb, xadj, hook, &ctx);
    out.params.E += xadj.E;
    out.params.gamma += xadj.gamma;
    out.params.tension_scale += xadj.tension_scale;
    out.params.alignment_time += xadj.alignment_time;
    // Traction adjoint.
    tadj.reset(n, out.network.size());
    kernel_traction_adjoint(in, nb, w, xadj.force, tadj);
    for (size_t i = 0; i < out.network.size(); ++i) out.network[i] += tadj.network[i];
    // Headway adjoint, then the drive's (the headway reads the drive's direction and free speed).
    hx.assign(n, Vec2::Zero());
    he.assign(n, Vec2::Zero());
    hu.assign(n, 0.0);
    headway_adjoint(in, nb, w, xadj.accel, hx, he, hu, out);
    in.time = step_time[static_cast<size_t>(k)];
    const std::vector<double> density = terms_density(in, w);
    const std::vector<double> ahead = material_density(in, st.x, st.heading, st.v);
    density_bar.assign(n, 0.0);
    heading_bar_later.resize(n, Vec2::Zero());
    for (size_t p = 0; p < n; ++p) {
      Vec2 gx = Vec2::Zero(), gv = Vec2::Zero();
      drive_adjoint(in, behaviours[static_cast<size_t>(w.behaviour[p])], w, p, st.heading[p], density, ahead, xadj.accel[p],
                    tadj.heading[p] + he[p] + heading_bar_later[p], hu[p], gx, gv, density_bar[p], out, f_own);
      xb[p] = xadj.x[p] + tadj.x[p] + hx[p] + gx;
      vb[p] = xadj.v[p] + tadj.v[p] + gv;
      out.params.comfort_distance += tadj.comfort[p];
      Cb[p] = xadj.C[p];
      Jb[p] = xadj.J[p];
    }
    // The material's density-speed law reads the density ahead, which the positions, the
    // headings and (with an opening speed) the velocities before the step make.
    if (material_density_law(P)) {
      heading_bar.assign(n, Vec2::Zero());
      material_density_vjp(in, st.x, st.heading, st.v, density_bar, xb, heading_bar, vb, &out.params.density_opening_speed);
      heading_bar_later.swap(heading_bar);
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
