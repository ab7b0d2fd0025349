// Images out: OpenEXR (RGBA, half or float, written with the OpenEXR library, string attributes
// in the header) and an 8-bit PNG preview (tone-mapped by the caller), for `lblight render`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace lblight {

// rgba: width x height x 4 floats, top row first. Writes `file` directly (the caller stages it).
// std_error (3 floats per pixel): a reference picture's standard errors, as float channels
// se.R, se.G, se.B beside RGBA.
void write_exr(const std::filesystem::path& file, int width, int height, const std::vector<float>& rgba, bool half,
               const std::map<std::string, std::string>& attributes, const std::vector<float>* std_error = nullptr);

// rgb: width x height x 3 bytes, top row first; an 8-bit RGB PNG (zlib).
void write_png(const std::filesystem::path& file, int width, int height, const std::vector<std::uint8_t>& rgb);
std::string encode_png(int width, int height, const std::vector<std::uint8_t>& rgb);  // the file's bytes
std::string base64(const std::string& bytes);  // for images embedded in SVG

// Reads back an EXR's RGBA as floats and its string attributes (tests, `lblight inspect`).
// std_error: the se.R/G/B channels of a reference picture, 3 floats per pixel (0 where absent).
std::vector<float> read_exr(const std::filesystem::path& file, int& width, int& height,
                            std::map<std::string, std::string>* attributes = nullptr,
                            std::vector<float>* std_error = nullptr);

}  // namespace lblight
