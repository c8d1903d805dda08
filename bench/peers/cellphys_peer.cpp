// cellphys itself, behind the peer interface: the scene's world from scene::build_world with
// the integrator, solver, tolerance, workers and step overridden by the configuration.
#include <stdexcept>

#include "bench/peers/peer.h"

namespace cellphys::bench {
namespace {

class CellphysPeer : public Peer {
 public:
  CellphysPeer(const scene::SceneDesc& scene, const EngineConfig& c) {
    scene::SceneDesc s = scene;
    if (!c.variant.empty()) {
      const size_t slash = c.variant.find('/');
      const std::string integ = c.variant.substr(0, slash);
      if (!spu::parse_integrator(integ, &s.settings.integrator))
        throw std::invalid_argument("unknown integrator '" + integ + "'");
      if (slash != std::string::npos && !spu::parse_solver(c.variant.substr(slash + 1), &s.settings.solver))
        throw std::invalid_argument("unknown solver '" + c.variant.substr(slash + 1) + "'");
    }
    if (c.dt > 0) s.settings.dt = static_cast<float>(c.dt);
    if (c.tolerance > 0) s.settings.tolerance = static_cast<float>(c.tolerance);
    if (c.workers > 0) s.settings.workers = c.workers;
    built_ = scene::build_world(s);
    label_ = std::string("cellphys ") + spu::integrator_name(s.settings.integrator) + "/" +
             spu::solver_name(s.settings.solver);
  }
  void step() override {
    const ppe::StepStats& st = built_.world->step();
    active_ = st.active_bodies;
    iterations_ = st.solves ? double(st.solver_iterations) / st.solves : 0.0;
    failed_ = st.failed_islands > 0;
  }
  State state(size_t i) const override {
    const ppe::BodyState b = built_.world->state(built_.bodies[i]);
    State s;
    for (int k = 0; k < 3; ++k) s.p[k] = b.position[k], s.v[k] = b.velocity[k], s.w[k] = b.angular_velocity[k];
    for (int k = 0; k < 4; ++k) s.q[k] = b.orientation[k];
    return s;
  }
  long active_bodies() const override { return active_; }
  double last_iterations() const override { return iterations_; }
  int last_step_failed() const override { return failed_; }
  std::string label() const override { return label_; }

 private:
  scene::BuiltScene built_;
  long active_ = -1;
  double iterations_ = -1;
  int failed_ = 0;
  std::string label_;
};

}  // namespace

std::unique_ptr<Peer> make_cellphys(const scene::SceneDesc& scene, const EngineConfig& c) {
  return std::make_unique<CellphysPeer>(scene, c);
}

}  // namespace cellphys::bench
