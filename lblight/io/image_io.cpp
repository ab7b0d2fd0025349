#include "lblight/io/image_io.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <Imath/half.h>
#include <zlib.h>

#include <array>
#include <cstring>
#include <fstream>

#include "lblight/core/error.h"

namespace lblight {

void write_exr(const std::filesystem::path& file, int width, int height, const std::vector<float>& rgba, bool half,
               const std::map<std::string, std::string>& attributes, const std::vector<float>* std_error) {
  if (rgba.size() != static_cast<std::size_t>(width) * height * 4 ||
      (std_error && std_error->size() != static_cast<std::size_t>(width) * height * 3))
    throw Error(ErrorCategory::Internal, "write_exr: pixel count does not match the size");
  try {
    Imf::Header header(width, height);
    const Imf::PixelType type = half ? Imf::HALF : Imf::FLOAT;
    const char* names[4] = {"R", "G", "B", "A"};
    for (const char* n : names) header.channels().insert(n, Imf::Channel(type));
    const char* se_names[3] = {"se.R", "se.G", "se.B"};
    if (std_error)
      for (const char* n : se_names) header.channels().insert(n, Imf::Channel(Imf::FLOAT));
    for (const auto& [key, value] : attributes) header.insert(key, Imf::StringAttribute(value));
    header.compression() = Imf::ZIP_COMPRESSION;
    // OpenEXR writes a frame buffer of the channels' own type: half is converted here.
    Imf::FrameBuffer fb;
    std::vector<Imath::half> halves;
    if (half) {
      halves.assign(rgba.begin(), rgba.end());
      char* base = reinterpret_cast<char*>(halves.data());
      for (int c = 0; c < 4; ++c)
        fb.insert(names[c], Imf::Slice(Imf::HALF, base + c * sizeof(Imath::half), 4 * sizeof(Imath::half),
                                       4 * sizeof(Imath::half) * static_cast<std::size_t>(width)));
    } else {
      char* base = reinterpret_cast<char*>(const_cast<float*>(rgba.data()));
      for (int c = 0; c < 4; ++c)
        fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 4 * sizeof(float),
                                       4 * sizeof(float) * static_cast<std::size_t>(width)));
    }
    if (std_error) {
      char* base = reinterpret_cast<char*>(const_cast<float*>(std_error->data()));
      for (int c = 0; c < 3; ++c)
        fb.insert(se_names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float),
                                          3 * sizeof(float) * static_cast<std::size_t>(width)));
    }
    Imf::OutputFile out(file.string().c_str(), header);
    out.setFrameBuffer(fb);
    out.writePixels(height);
  } catch (const std::exception& e) {
    throw Error(ErrorCategory::Io, std::string("cannot write OpenEXR: ") + e.what(), {file.string(), {}, {}});
  }
}

std::vector<float> read_exr(const std::filesystem::path& file, int& width, int& height,
                            std::map<std::string, std::string>* attributes, std::vector<float>* std_error) {
  try {
    Imf::InputFile in(file.string().c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    width = dw.max.x - dw.min.x + 1;
    height = dw.max.y - dw.min.y + 1;
    std::vector<float> rgba(static_cast<std::size_t>(width) * height * 4, 0.0f);
    Imf::FrameBuffer fb;
    const char* names[4] = {"R", "G", "B", "A"};
    char* base = reinterpret_cast<char*>(rgba.data()) -
                 (static_cast<std::ptrdiff_t>(dw.min.x) + static_cast<std::ptrdiff_t>(dw.min.y) * width) * 4 * sizeof(float);
    for (int c = 0; c < 4; ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 4 * sizeof(float), 4 * sizeof(float) * width));
    if (std_error) {  // a reference picture's se.R, se.G, se.B (0 where the file has none)
      std_error->assign(static_cast<std::size_t>(width) * height * 3, 0.0f);
      char* se_base = reinterpret_cast<char*>(std_error->data()) -
                      (static_cast<std::ptrdiff_t>(dw.min.x) + static_cast<std::ptrdiff_t>(dw.min.y) * width) * 3 *
                          sizeof(float);
      const char* se_names[3] = {"se.R", "se.G", "se.B"};
      for (int c = 0; c < 3; ++c)
        fb.insert(se_names[c], Imf::Slice(Imf::FLOAT, se_base + c * sizeof(float), 3 * sizeof(float),
                                          3 * sizeof(float) * width, 1, 1, 0.0));
    }
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    if (attributes)
      for (auto it = in.header().begin(); it != in.header().end(); ++it)
        if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) (*attributes)[it.name()] = s->value();
    return rgba;
  } catch (const std::exception& e) {
    throw_invalid(std::string("not a readable OpenEXR file: ") + e.what(), {file.string(), {}, {}});
  }
}

namespace {

void put32(std::string& s, std::uint32_t v) {
  for (int k = 3; k >= 0; --k) s.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
}

void chunk(std::string& out, const char* type, const std::string& data) {
  std::string c;
  put32(c, static_cast<std::uint32_t>(data.size()));
  c.append(type, 4);
  c += data;
  const std::uint32_t crc = static_cast<std::uint32_t>(
      crc32(0, reinterpret_cast<const Bytef*>(c.data() + 4), static_cast<uInt>(c.size() - 4)));
  put32(c, crc);
  out += c;
}

}  // namespace

std::string encode_png(int width, int height, const std::vector<std::uint8_t>& rgb) {
  if (rgb.size() != static_cast<std::size_t>(width) * height * 3)
    throw Error(ErrorCategory::Internal, "encode_png: pixel count does not match the size");
  std::string raw;
  raw.reserve(static_cast<std::size_t>(height) * (1 + 3 * width));
  for (int y = 0; y < height; ++y) {
    raw.push_back('\0');  // filter: none
    raw.append(reinterpret_cast<const char*>(rgb.data()) + static_cast<std::size_t>(y) * 3 * width, 3 * width);
  }
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string packed(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(packed.data()), &size, reinterpret_cast<const Bytef*>(raw.data()),
                static_cast<uLong>(raw.size()), 6) != Z_OK)
    throw Error(ErrorCategory::Internal, "encode_png: zlib failed");
  packed.resize(size);
  std::string out("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  put32(ihdr, static_cast<std::uint32_t>(width));
  put32(ihdr, static_cast<std::uint32_t>(height));
  ihdr += std::string("\x08\x02\x00\x00\x00", 5);  // 8 bits, RGB, deflate, no filter, no interlace
  chunk(out, "IHDR", ihdr);
  chunk(out, "IDAT", packed);
  chunk(out, "IEND", "");
  return out;
}

void write_png(const std::filesystem::path& file, int width, int height, const std::vector<std::uint8_t>& rgb) {
  const std::string bytes = encode_png(width, height, rgb);
  std::ofstream out(file, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw Error(ErrorCategory::Io, "cannot write", {file.string(), {}, {}});
}

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const std::uint32_t a = static_cast<unsigned char>(in[i]);
    const std::uint32_t b = i + 1 < in.size() ? static_cast<unsigned char>(in[i + 1]) : 0;
    const std::uint32_t c = i + 2 < in.size() ? static_cast<unsigned char>(in[i + 2]) : 0;
    const std::uint32_t v = (a << 16) | (b << 8) | c;
    out.push_back(t[(v >> 18) & 63]);
    out.push_back(t[(v >> 12) & 63]);
    out.push_back(i + 1 < in.size() ? t[(v >> 6) & 63] : '=');
    out.push_back(i + 2 < in.size() ? t[v & 63] : '=');
  }
  return out;
}

}  // namespace lblight
