// Haar-compressed sub-block streams (docs/model.md sec. 7; [Steele2009] secs. 2.3, 4.5, 5.3): encoding one base
// solution, measuring what the compression cost, and writing the .lbh file of a model
// (docs/lbh-format.md). Readers use readers/lbh/lbh_reader.h.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/compress/lbh_settings.h"
#include "lblight/lattice/dense_grid.h"
#include "readers/lbh/lbh_reader.h"

namespace lblight {

// Every solution of one file shares one lattice, a DenseFrame (lattice/dense_grid.h).

struct LbhSolutionIn {
  std::string name;                       // grid name, at most 15 ASCII characters ("B05", "light")
  int index = -1;                         // base solution 0..18, -1 otherwise
  std::array<int, 3> direction{};
  const std::array<std::vector<float>, 3>* rgb = nullptr;  // R, G, B per node, x fastest
};

// What compressing one solution cost. Errors are over the decoded lattice nodes (each node from
// the sub-block the sampler reads it from), all three channels.
struct LbhStats {
  std::uint64_t nodes = 0, blocks = 0, fast_blocks = 0, coefficients = 0;
  std::uint64_t float_rgb_bytes = 0;  // nodes x 3 x 4
  std::uint64_t stream_bytes = 0;     // masks (8) + offsets (4) per block + coefficients as stored
  double ratio = 0;                   // float_rgb_bytes / stream_bytes
  double max_abs_value = 0;           // largest |value| of the original (the relative scale)
  double threshold = 0;               // absolute threshold applied
  double rms_error = 0, max_abs_error = 0;  // over nodes and channels
  double max_abs_error_block = 0;     // over every stored value, forward borders included
  double error_bound = 0;             // max over values of the sum of coefficient errors (dropped or
                                      // quantised) on its path
  double encode_seconds = 0;
};

struct LbhEncoded {
  std::string name;
  int index = -1;
  std::array<int, 3> direction{};
  LbhSettings requested;
  float threshold = 0;      // absolute, as applied and stored
  float max_abs_value = 0;
  lbh::Encoding encoding = lbh::Encoding::F32;
  float step = 0;           // Q8: value of one integer step; F32: 0
  std::vector<std::uint64_t> masks;
  std::vector<std::uint32_t> offsets;
  std::vector<float> coeffs;         // F32: kept coefficients, 3 floats each; Q8: block averages
  std::vector<std::int8_t> details;  // Q8: kept details, 3 integers each
  LbhStats stats;
};

// Encodes one solution with `threads` threads (0 = all cores). Throws Error(InvalidInput) on
// non-finite values or a negative/non-finite threshold. The result does not depend on the
// thread count.
LbhEncoded encode_lbh_solution(const DenseFrame& frame, const LbhSolutionIn& in, const LbhSettings& threshold,
                               int threads = 0);

// The file bytes (docs/lbh-format.md) for the given solutions, in order.
std::string serialize_lbh(const DenseFrame& frame, const std::vector<LbhEncoded>& solutions);

// Writes serialize_lbh() to `file` through a temporary name and a rename.
void write_lbh(const std::filesystem::path& file, const DenseFrame& frame, const std::vector<LbhEncoded>& solutions);

// Manifest entry of one compressed solution ("compression" in manifest.json).
nlohmann::json lbh_stats_json(const LbhEncoded& e, const std::string& file_name);

}  // namespace lblight
