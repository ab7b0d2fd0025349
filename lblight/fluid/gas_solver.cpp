#include "lblight/fluid/gas_solver.h"

#include <omp.h>

#include <algorithm>
#include <cmath>

#include "lblight/core/error.h"
#include "lblight/fluid/bgk.h"

namespace lblight::fluid {
namespace {

using d3q19::cx;
using d3q19::cy;
using d3q19::cz;
using d3q19::kQ;

constexpr double kMinTau = 0.503;  // nu = (tau - 1/2) / 3 >= 1e-3
constexpr double kMaxMach = 0.3;
const double kSoundSpeed = 1.0 / std::sqrt(3.0);

}  // namespace

std::string check_gas_settings(const GasSettings& s) {
  const Dims& d = s.dims;
  if (d.nx < 1 || d.ny < 1 || d.nz < 1 || d.count() > (std::size_t{1} << 31))
    return "gas domain " + std::to_string(d.nx) + "x" + std::to_string(d.ny) + "x" + std::to_string(d.nz) +
           " nodes; allowed: at least 1 per axis, at most 2^31 nodes";
  if (!(s.tau >= kMinTau) || !(s.tau <= 5.0))
    return "relaxation time tau = " + message_number(s.tau) +
           " is unstable or too viscous; allowed: 0.503 <= tau <= 5 (viscosity (tau - 1/2)/3 from 1e-3 to 1.5)";
  for (const double t : {s.tau_temperature, s.tau_smoke})
    if (!(t >= kMinTau) || !(t <= 5.0))
      return "scalar relaxation time (tau_temperature, tau_smoke) " + message_number(t) +
             "; allowed: 0.503 <= tau <= 5 (diffusivity (tau - 1/2)/4)";
  for (const double f : s.force)
    if (!std::isfinite(f) || std::fabs(f) > 1e-2) return "body force " + message_number(f) + " per node; allowed: |F| <= 0.01";
  if (!std::isfinite(s.buoyancy) || std::fabs(s.buoyancy) > 1.0 || !std::isfinite(s.t_ambient))
    return "buoyancy " + message_number(s.buoyancy) + "; allowed: |H g| <= 1 per unit temperature";
  if (!s.solid.empty() && s.solid.size() != d.count()) return "the obstacle mask does not match the domain's nodes";
  if (s.inlet.enabled) {
    const Inlet& in = s.inlet;
    if (in.x0 < 0 || in.y0 < 0 || in.x1 >= d.nx || in.y1 >= d.ny || in.x1 < in.x0 || in.y1 < in.y0)
      return "inlet patch outside the floor of the domain";
    if (!in.mask.empty() && in.mask.size() != static_cast<std::size_t>(d.nx) * d.ny)
      return "the inlet mask does not match the floor's nodes";
    const double mach = std::fabs(in.speed) / kSoundSpeed;
    if (!(mach <= kMaxMach))
      return "inlet speed " + message_number(in.speed) + " is Mach " + message_number(mach) +
             "; allowed: Mach <= 0.3 (speed <= 0.173 lattice units per step): BGK is a low-Mach model";
    if (!std::isfinite(in.temperature) || !std::isfinite(in.smoke) || in.smoke < 0)
      return "inlet temperature and smoke must be finite, smoke >= 0";
  }
  return {};
}

GasSolver::GasSolver(const GasSettings& settings) : s_(settings) {
  const std::string why = check_gas_settings(s_);
  if (!why.empty()) throw_invalid(why);
  n_ = s_.dims.count();
  threads_ = s_.threads > 0 ? s_.threads : std::max(1, omp_get_max_threads());
  if (s_.solid.empty()) s_.solid.assign(n_, 0);
  const Dims& d = s_.dims;
  row_has_solid_.assign(row_of(0, d.nz), 0);
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x)
        if (s_.solid[d.index(x, y, z)]) row_has_solid_[row_of(y, z)] = 1;
  row_streams_plainly_.assign(row_has_solid_.size(), 0);  // set for rows inside the box in y and z
  for (int z = 1; z + 1 < d.nz; ++z)
    for (int y = 1; y + 1 < d.ny; ++y) {
      bool plain = true;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          plain = plain && !row_has_solid_[row_of(y + dy, z + dz)];
      row_streams_plainly_[row_of(y, z)] = plain;
    }
  f_.assign(kQ * n_, 0.0f);
  t_.assign(kQ7 * n_, 0.0f);
  c_.assign(kQ7 * n_, 0.0f);
  f_post_ = f_;
  t_post_ = t_;
  c_post_ = c_;
  rho_.assign(n_, 1.0);
  ux_.assign(n_, 0.0);
  uy_.assign(n_, 0.0);
  uz_.assign(n_, 0.0);
  temp_.assign(n_, s_.t_ambient);
  smoke_.assign(n_, 0.0);
  set_state(std::vector<double>(n_, 1.0), {}, std::vector<double>(n_, s_.t_ambient), std::vector<double>(n_, 0.0));
}

void GasSolver::set_state(const std::vector<double>& rho, const std::array<std::vector<double>, 3>& u,
                          const std::vector<double>& temperature, const std::vector<double>& smoke) {
  const std::vector<double> current = rho.empty() ? density() : std::vector<double>{};
  for (std::size_t i = 0; i < n_; ++i) {
    if (s_.solid[i]) continue;
    const double r = rho.empty() ? current[i] : rho[i];
    if (!u[0].empty()) {
      ux_[i] = u[0][i];
      uy_[i] = u[1][i];
      uz_[i] = u[2][i];
    }
    if (!rho.empty() || !u[0].empty())
      for (int m = 0; m < kQ; ++m) f_[m * n_ + i] = static_cast<float>(equilibrium<double>(m, r, ux_[i], uy_[i], uz_[i]));
    auto set_scalar = [&](std::vector<float>& g, const std::vector<double>& v) {
      if (v.empty()) return;
      for (int k = 0; k < kQ7; ++k) g[k * n_ + i] = static_cast<float>(scalar_equilibrium(k, v[i], ux_[i], uy_[i], uz_[i]));
    };
    set_scalar(t_, temperature);
    set_scalar(c_, smoke);
  }
}

double GasSolver::scalar(const std::vector<float>& g, std::size_t i) const {
  double s = 0;
  for (int k = 0; k < kQ7; ++k) s += g[k * n_ + i];
  return s;
}

GasView settings_view(const GasSettings& s) {
  GasView v;
  v.nx = s.dims.nx, v.ny = s.dims.ny, v.nz = s.dims.nz;
  v.n = s.dims.count();
  v.tau = s.tau, v.tau_temperature = s.tau_temperature, v.tau_smoke = s.tau_smoke;
  for (int a = 0; a < 3; ++a) v.force[a] = s.force[static_cast<std::size_t>(a)];
  v.buoyancy = s.buoyancy, v.t_ambient = s.t_ambient;
  for (int k = 0; k < 6; ++k) v.faces[k] = s.faces[static_cast<std::size_t>(k)];
  v.solid = s.solid.data();
  v.any_solid = std::any_of(s.solid.begin(), s.solid.end(), [](std::uint8_t b) { return b != 0; });
  const Inlet& in = s.inlet;
  v.inlet = in.enabled;
  v.inlet_x0 = in.x0, v.inlet_x1 = in.x1, v.inlet_y0 = in.y0, v.inlet_y1 = in.y1;
  v.inlet_mask = in.mask.empty() ? nullptr : in.mask.data();
  v.inlet_speed = in.speed, v.inlet_temperature = in.temperature, v.inlet_smoke = in.smoke;
  return v;
}

GasView GasSolver::view() {
  GasView v = settings_view(s_);  // scans the obstacle bytes: 4 times a step, a fraction of a percent
  v.f = f_.data(), v.t = t_.data(), v.c = c_.data();
  v.f_post = f_post_.data(), v.t_post = t_post_.data(), v.c_post = c_post_.data();
  v.rho = rho_.data(), v.ux = ux_.data(), v.uy = uy_.data(), v.uz = uz_.data();
  v.temperature = temp_.data(), v.smoke = smoke_.data();
  return v;
}

void GasSolver::collide_all() {
  const GasView v = view();
  const Dims& d = s_.dims;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_)
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y) {
      const std::size_t row = d.index(0, y, z);
      // Runs of fluid nodes (the whole row where it holds no obstacle), each with no branch
      // inside: GCC vectorises it across nodes (8 doubles a vector on AVX-512).
      const bool obstacles = row_has_solid_[row_of(y, z)];
      for (int a = 0; a < d.nx;) {
        int b = obstacles ? a : d.nx;
        while (b < d.nx && !v.solid[row + static_cast<std::size_t>(b)]) ++b;
#pragma omp simd
        for (int x = a; x < b; ++x) collide_fluid_node(v, row + static_cast<std::size_t>(x));
        a = b + 1;  // past the solid node that ended the run (left alone)
      }
    }
}

template <int Q>
void GasSolver::stream(GasLattice lattice, const float* post, float* next) {
  const GasView v = view();
  const Dims& d = s_.dims;
  const long long nx = d.nx, plane = nx * d.ny, n = static_cast<long long>(n_);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_)
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y) {
      if (y == 0 || z == 0 || y == d.ny - 1 || z == d.nz - 1 || d.nx < 3) {
        for (int x = 0; x < d.nx; ++x) stream_node<Q>(v, lattice, post, next, x, y, z);
        continue;
      }
      // Inside the box in y and z, every source of the row's inner nodes lies inside it:
      // stream_node's interior cases as one shifted copy per direction (with bounce-back and
      // solid nodes as selects where the rows around hold obstacles). The end nodes meet the x faces.
      stream_node<Q>(v, lattice, post, next, 0, y, z);
      stream_node<Q>(v, lattice, post, next, d.nx - 1, y, z);
      const bool plain = row_streams_plainly_[row_of(y, z)];
      const long long row = static_cast<long long>(d.index(0, y, z));
      for (int m = 0; m < Q; ++m) {
        const long long shift = cx(m) + nx * cy(m) + plane * cz(m);
        const float* __restrict src = post + m * n + row - shift;
        float* __restrict dst = next + m * n + row;
        if (plain) {
#pragma omp simd
          for (int x = 1; x < d.nx - 1; ++x) dst[x] = src[x];
        } else {
          const float* __restrict bounce = post + d3q19::opposite(m) * n + row;
          const std::uint8_t* solid = v.solid + row;
          const std::uint8_t* solid_src = v.solid + row - shift;
#pragma omp simd
          for (int x = 1; x < d.nx - 1; ++x) dst[x] = solid[x] ? dst[x] : (solid_src[x] ? bounce[x] : src[x]);
        }
      }
    }
}

void GasSolver::step(int steps) {
  for (int t = 0; t < steps; ++t) {
    collide_all();
    stream<kQ>(kFlowLattice, f_post_.data(), f_.data());
    stream<kQ7>(kTemperatureLattice, t_post_.data(), t_.data());
    stream<kQ7>(kSmokeLattice, c_post_.data(), c_.data());
    ++steps_;
  }
}

std::vector<double> GasSolver::density() const {
  std::vector<double> out(n_, 0.0);
  for (std::size_t i = 0; i < n_; ++i)
    if (!s_.solid[i])
      for (int m = 0; m < kQ; ++m) out[i] += f_[m * n_ + i];
  return out;
}

std::array<std::vector<double>, 3> GasSolver::velocity() const { return {ux_, uy_, uz_}; }

std::vector<double> GasSolver::temperature() const {
  std::vector<double> out(n_, 0.0);
  for (std::size_t i = 0; i < n_; ++i)
    if (!s_.solid[i]) out[i] = scalar(t_, i);
  return out;
}

std::vector<double> GasSolver::smoke() const {
  std::vector<double> out(n_, 0.0);
  for (std::size_t i = 0; i < n_; ++i)
    if (!s_.solid[i]) out[i] = scalar(c_, i);
  return out;
}

std::pair<double, std::size_t> GasSolver::fastest_node() const {
  double fastest = 0;
  std::size_t at = 0;
  for (std::size_t i = 0; i < n_; ++i) {
    double v = std::sqrt(ux_[i] * ux_[i] + uy_[i] * uy_[i] + uz_[i] * uz_[i]);
    if (!std::isfinite(v)) v = 1e300;
    if (v > fastest) fastest = v, at = i;
  }
  return {fastest, at};
}

double GasSolver::total_mass() const {
  double m = 0;
  for (double r : density()) m += r;
  return m;
}

std::array<double, 3> GasSolver::total_momentum() const {
  std::array<double, 3> j{0, 0, 0};
  for (std::size_t i = 0; i < n_; ++i)
    if (!s_.solid[i])
      for (int m = 1; m < kQ; ++m) {
        j[0] += f_[m * n_ + i] * cx(m);
        j[1] += f_[m * n_ + i] * cy(m);
        j[2] += f_[m * n_ + i] * cz(m);
      }
  return j;
}

}  // namespace lblight::fluid
