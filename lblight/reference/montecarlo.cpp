#include "lblight/reference/montecarlo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "lblight/core/random_walk.h"
#include "lblight/core/system_info.h"
#include "lblight/lattice/d3q19.h"

namespace lblight {

Illumination base_solution_light(int index) {
  if (index == 0) return {{LightSource::Kind::Isotropic, {}, 18.0}};
  const double len = std::sqrt(static_cast<double>(d3q19::length_sq(index)));
  return {{LightSource::Kind::Collimated,
           {d3q19::cx(index) / len, d3q19::cy(index) / len, d3q19::cz(index) / len},
           1.0}};
}

Illumination static_light(const std::array<double, 3>& travel_direction, double intensity, double ambient) {
  Illumination light;
  if (intensity > 0) light.push_back({LightSource::Kind::Collimated, travel_direction, intensity});
  if (ambient > 0) light.push_back({LightSource::Kind::Isotropic, {}, 18.0 * ambient});
  return light;
}

namespace {

constexpr double kFixedScale = 1073741824.0;  // 2^30: scores are summed as integers of this unit
constexpr double kRouletteWeight = 0.1;       // below it a photon survives with probability w / 0.1

using Vec = std::array<double, 3>;
using PhotonRng = CounterRng;
constexpr double kPi = 3.14159265358979323846;

// Where photons start: faces of the interior box [0.5, n - 1.5] per axis (node i is the centre of
// the unit voxel [i - 0.5, i + 0.5]), each with its share of the incident power. Over a ground the
// box starts at the ground layer's top face, nothing enters through the ground, the source's light
// from below is hidden by the ground (beams going up, the lower half of isotropic light), and the
// open ground outside sends in its reflection of the downward light: radiance A E / pi, upward,
// through the sides.
struct EntryFace {
  int face = 0;  // 2 axis + (0: the low side, 1: the high side)
  const LightSource* source = nullptr;
  double power = 0;
  bool from_ground = false;  // the open ground's diffuse light (Lambertian, upward only)
  bool from_above = false;   // isotropic light through a side over a ground: its downward half only
};

// Irradiance a source puts on a horizontal plane from above.
double downward_irradiance(const LightSource& s) {
  return s.kind == LightSource::Kind::Collimated ? s.fluence * std::max(0.0, -s.direction[2]) : s.fluence / 4.0;
}

// Fluence of a source in open air over a ground: the ground hides a beam going up and the lower
// half of isotropic light, and reflects 2 A E (radiance A E / pi over the upper hemisphere).
double fluence_over_ground(const LightSource& s, double albedo) {
  const double direct = s.kind == LightSource::Kind::Collimated ? (s.direction[2] > 0.0 ? 0.0 : s.fluence)
                                                                 : s.fluence / 2.0;
  return direct + 2.0 * albedo * downward_irradiance(s);
}

// A cosine-weighted direction about `axis`, pointing to its high side unless `low`.
Vec lambertian(PhotonRng& rng, int axis, bool low) {
  const double c = std::sqrt(rng.uniform()), sn = std::sqrt(std::max(0.0, 1.0 - c * c));
  const double phi = 2.0 * kPi * rng.uniform();
  Vec d;
  const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
  d[axis] = low ? -c : c;
  d[a1] = sn * std::cos(phi);
  d[a2] = sn * std::sin(phi);
  return d;
}

class Sources {
 public:
  // ground_layer: the lattice z of the ground nodes (-1: none), albedo its albedo.
  Sources(const Dims& dims, const Illumination& light, bool periodic_xy, int ground_layer, double albedo)
      : periodic_(periodic_xy) {
    lo_ = {0.5, 0.5, ground_layer >= 0 ? ground_layer + 0.5 : 0.5};
    ext_ = {static_cast<double>(dims.nx - 2), static_cast<double>(dims.ny - 2), dims.nz - 1.5 - lo_[2]};
    for (const LightSource& s : light) {
      for (int axis = periodic_xy ? 2 : 0; axis < 3; ++axis) {
        const double area = ext_[(axis + 1) % 3] * ext_[(axis + 2) % 3];
        const bool bottom_closed = axis == 2 && ground_layer >= 0;
        const bool ground = ground_layer >= 0;
        if (s.kind == LightSource::Kind::Collimated) {
          const double dn = s.direction[axis];
          if (ground && s.direction[2] > 0.0) continue;  // a beam from below the horizon
          if (dn > 0.0 && !bottom_closed) add(2 * axis, &s, s.fluence * area * dn);
          if (dn < 0.0) add(2 * axis + 1, &s, s.fluence * area * -dn);
        } else if (ground && axis < 2) {  // through a side: only the half that comes from above
          for (int side = 0; side < 2; ++side) add(2 * axis + side, &s, s.fluence * area / 8.0, false, true);
        } else {  // radiance fluence / 4 pi: pi times that enters per unit area
          if (!bottom_closed) add(2 * axis, &s, s.fluence * area / 4.0);
          add(2 * axis + 1, &s, s.fluence * area / 4.0);
        }
        // radiance L = A E / pi from the upward half of a side face's inward hemisphere: pi L / 2
        if (ground_layer >= 0 && axis < 2)
          for (int side = 0; side < 2; ++side)
            add(2 * axis + side, &s, albedo * downward_irradiance(s) / 2.0 * area, true);
      }
    }
  }
  double power() const { return total_; }

  // Position and direction of a new photon.
  void emit(PhotonRng& rng, Vec& p, Vec& d) const {
    const double u = rng.uniform() * total_;
    std::size_t k = 0;
    while (k + 1 < faces_.size() && u > cumulative_[k]) ++k;
    const EntryFace& f = faces_[k];
    const int axis = f.face / 2;
    const bool high = f.face % 2 == 1;
    for (int a = 0; a < 3; ++a) p[a] = lo_[a] + rng.uniform() * ext_[a];
    p[axis] = high ? lo_[axis] + ext_[axis] : lo_[axis];
    if (f.source->kind == LightSource::Kind::Collimated && !f.from_ground) {
      d = f.source->direction;
      return;
    }
    // Lambertian into the box: cos(theta) = sqrt(u) about the inward normal.
    d = lambertian(rng, axis, high);
    if (f.from_ground) d[2] = std::abs(d[2]);  // the upward half, which the same law gives mirrored
    if (f.from_above) d[2] = -std::abs(d[2]);
  }

 private:
  void add(int face, const LightSource* s, double power, bool from_ground = false, bool from_above = false) {
    if (!(power > 0)) return;
    total_ += power;
    faces_.push_back({face, s, power, from_ground, from_above});
    cumulative_.push_back(total_);
  }
  bool periodic_;
  Vec lo_{}, ext_{};
  std::vector<EntryFace> faces_;
  std::vector<double> cumulative_;
  double total_ = 0;
};

void add_fixed(std::int64_t& slot, double value) {
  const auto q = static_cast<std::int64_t>(std::llround(value * kFixedScale));
  if (q != 0) __atomic_fetch_add(&slot, q, __ATOMIC_RELAXED);
}

struct BatchTally {
  std::vector<std::int64_t> track;  // per node: sum of weight x path length
  std::array<std::int64_t, 6> escaped{};
  std::int64_t lost = 0;
};

// One photon from emission to escape, absorption or roulette.
// ground_layer >= 0: photons entering that layer are reflected at its top face with `albedo`.
void trace_photon(const LatticeGeometry& lat, const ChannelOptics& optics, const Sources& sources, bool periodic_xy,
                  int ground_layer, double albedo, PhotonRng& rng, BatchTally& tally) {
  const Dims& dims = lat.dims;
  const int n[3] = {dims.nx, dims.ny, dims.nz};
  const int z_min = ground_layer >= 0 ? ground_layer + 1 : 1;
  Vec p, d;
  sources.emit(rng, p, d);
  int v[3];
  for (int a = 0; a < 3; ++a) v[a] = std::clamp(static_cast<int>(std::floor(p[a] + 0.5)), a == 2 ? z_min : 1, n[a] - 2);
  double w = 1.0;
  double tau = -std::log(rng.uniform());
  int collisions = 0;
  for (;;) {
    // Distance to the voxel's exit and the axis it crosses.
    double t = std::numeric_limits<double>::infinity();
    int axis = 0;
    for (int a = 0; a < 3; ++a) {
      double ta;
      if (d[a] > 0)
        ta = (v[a] + 0.5 - p[a]) / d[a];
      else if (d[a] < 0)
        ta = (v[a] - 0.5 - p[a]) / d[a];
      else
        continue;
      if (ta < t) t = ta, axis = a;
    }
    t = std::max(t, 0.0);
    const std::size_t idx = dims.index(v[0], v[1], v[2]);
    const OpticalParams& op = optics[lat.material[idx]];
    const double mu = static_cast<double>(lat.density[idx]) * op.sigma_t();
    if (mu * t > tau) {  // collides inside this voxel
      const double s = tau / mu;
      add_fixed(tally.track[idx], w * s);
      for (int a = 0; a < 3; ++a) p[a] += s * d[a];
      w *= op.sigma_s / op.sigma_t();
      if (w < kRouletteWeight) {
        if (rng.uniform() * kRouletteWeight < w) {
          w = kRouletteWeight;
        } else {
          return;
        }
      }
      if (++collisions > kMaxCollisions) {
        add_fixed(tally.lost, w);
        return;
      }
      const double u1 = rng.uniform(), u2 = rng.uniform();
      d = scatter_hg(d, op.g, u1, u2);
      tau = -std::log(rng.uniform());
      continue;
    }
    add_fixed(tally.track[idx], w * t);
    tau -= mu * t;
    for (int a = 0; a < 3; ++a) p[a] += t * d[a];
    const int step = d[axis] > 0 ? 1 : -1;
    p[axis] = v[axis] + 0.5 * step;
    if (axis == 2 && step < 0 && v[2] == z_min && ground_layer >= 0) {  // reaches the ground
      add_fixed(tally.escaped[4], w * (1.0 - albedo));
      w *= albedo;
      if (w < kRouletteWeight) {
        if (!(w > 0) || rng.uniform() * kRouletteWeight >= w) return;
        w = kRouletteWeight;
      }
      d = lambertian(rng, 2, false);
      continue;
    }
    v[axis] += step;
    if (v[axis] >= 1 && v[axis] <= n[axis] - 2) continue;
    if (periodic_xy && axis < 2) {  // wrap to the other side
      const int span = n[axis] - 2;
      v[axis] += step > 0 ? -span : span;
      p[axis] += step > 0 ? -span : span;
      continue;
    }
    add_fixed(tally.escaped[2 * axis + (step > 0 ? 1 : 0)], w);
    return;
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

FluenceEstimate trace_fluence(const LatticeGeometry& lat, const ChannelOptics& optics, const Illumination& light,
                              const MonteCarloOptions& o, std::uint64_t stream, const RunContext& ctx,
                              const std::function<void(const FluenceEstimate&)>& after_batch) {
  check_geometry(lat, "montecarlo");
  if (!(o.target_error > 0) && !(o.time_budget > 0) && o.max_photons == 0)
    throw std::logic_error("trace_fluence: no target error, time budget or photon cap: it would never stop");
  if (o.photons_per_batch == 0 || o.min_batches < 2) throw std::logic_error("trace_fluence: empty batches");
  const auto t0 = std::chrono::steady_clock::now();
  const Dims& dims = lat.dims;
  const std::size_t count = dims.count();
  check_host_memory(kMonteCarloBytesPerNode * static_cast<double>(count), "the Monte Carlo reference's tallies",
                    "use a coarser density grid");
  int ground_layer = -1;
  if (o.ground_albedo >= 0)
    for (int z = 1; z + 1 < dims.nz && ground_layer < 0; ++z)
      if (lat.material[dims.index(1, 1, z)] == kMaterialGround) ground_layer = z;
  const double albedo = std::max(0.0, o.ground_albedo);
  const Sources sources(dims, light, o.periodic_xy, ground_layer, albedo);

  // Which nodes the error is measured on: the occupied ones, else every interior one.
  std::vector<std::size_t> measured;
  for (int z = 1; z + 1 < dims.nz; ++z)
    for (int y = 1; y + 1 < dims.ny; ++y)
      for (int x = 1; x + 1 < dims.nx; ++x)
        if (lat.density[dims.index(x, y, z)] > 0.0f && lat.material[dims.index(x, y, z)] != kMaterialGround)
          measured.push_back(dims.index(x, y, z));
  if (measured.empty())
    for (int z = 1; z + 1 < dims.nz; ++z)
      for (int y = 1; y + 1 < dims.ny; ++y)
        for (int x = 1; x + 1 < dims.nx; ++x) measured.push_back(dims.index(x, y, z));

  double empty_fluence = 0;
  for (const LightSource& s : light) empty_fluence += ground_layer >= 0 ? fluence_over_ground(s, albedo) : s.fluence;

  FluenceEstimate est;
  est.power.incident = sources.power();
  std::vector<double> sum(count, 0.0), sum_sq(count, 0.0);
  std::array<double, 6> esc_sum{}, esc_sq{};
  double abs_sum = 0, abs_sq = 0, lost_sum = 0;
  BatchTally tally;
  tally.track.assign(count, 0);

  // Fills est's mean and standard errors from the batches so far.
  auto summarise = [&](bool full) {
    const double b = est.batches;
    auto se_of = [b](double s, double sq) {
      const double m = s / b;
      return b > 1 ? std::sqrt(std::max(0.0, sq / b - m * m) / (b - 1)) : 0.0;
    };
    double se2 = 0, m2 = 0;
    for (std::size_t i : measured) {
      const double se = se_of(sum[i], sum_sq[i]), m = sum[i] / b;
      se2 += se * se;
      m2 += m * m;
    }
    est.relative_error = m2 > 0 ? std::sqrt(se2 / m2) : std::numeric_limits<double>::infinity();
    for (int f = 0; f < 6; ++f) {
      est.power.escaped[f] = esc_sum[f] / b;
      est.power.escaped_se[f] = se_of(esc_sum[f], esc_sq[f]);
    }
    est.power.absorbed = abs_sum / b;
    est.power.absorbed_se = se_of(abs_sum, abs_sq);
    est.power.lost = lost_sum / b;
    est.seconds = seconds_since(t0);
    if (!full) return;
    est.mean.assign(count, empty_fluence);
    est.std_error.assign(count, 0.0);
    for (int z = 1; z + 1 < dims.nz; ++z)
      for (int y = 1; y + 1 < dims.ny; ++y)
        for (int x = 1; x + 1 < dims.nx; ++x) {
          const std::size_t i = dims.index(x, y, z);
          est.mean[i] = sum[i] / b;
          est.std_error[i] = se_of(sum[i], sum_sq[i]);
        }
  };

  if (!(sources.power() > 0)) {  // e.g. a sun below the horizon over a ground: no light, exactly
    est.mean.assign(count, 0.0);
    est.std_error.assign(count, 0.0);
    est.relative_error = 0.0;
    if (after_batch) after_batch(est);
    return est;
  }
  tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
  const std::uint64_t per_batch = o.photons_per_batch;
  const double scale = sources.power() / static_cast<double>(per_batch) / kFixedScale;
  for (;;) {
    ctx.check_cancelled();
    const std::uint64_t first = est.photons;
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::uint64_t>(0, per_batch, 64), [&](const auto& r) {
        for (std::uint64_t k = r.begin(); k != r.end(); ++k) {
          PhotonRng rng(o.seed, stream, first + k);
          trace_photon(lat, optics, sources, o.periodic_xy, ground_layer, albedo, rng, tally);
        }
      });
    });
    est.photons += per_batch;
    ++est.batches;
    double absorbed = 0;
    for (std::size_t i = 0; i < count; ++i) {
      const double f = static_cast<double>(tally.track[i]) * scale;
      tally.track[i] = 0;
      sum[i] += f;
      sum_sq[i] += f * f;
      if (lat.material[i] != kMaterialGround) absorbed += static_cast<double>(lat.density[i]) * optics[lat.material[i]].sigma_a * f;
    }
    abs_sum += absorbed;
    abs_sq += absorbed * absorbed;
    for (int f = 0; f < 6; ++f) {
      const double e = static_cast<double>(tally.escaped[f]) * scale;
      esc_sum[f] += e;
      esc_sq[f] += e * e;
      tally.escaped[f] = 0;
    }
    lost_sum += static_cast<double>(tally.lost) * scale;
    tally.lost = 0;

    const bool enough = est.batches >= o.min_batches;
    summarise(false);
    const bool done = enough && ((o.target_error > 0 && est.relative_error <= o.target_error) ||
                                 (o.time_budget > 0 && est.seconds >= o.time_budget) ||
                                 (o.max_photons > 0 && est.photons >= o.max_photons));
    if (done || after_batch) summarise(true);
    if (after_batch) after_batch(est);
    if (done) break;
  }
  return est;
}

}  // namespace lblight
