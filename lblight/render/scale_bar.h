// The legend of a false-colour picture (`lblight render --grid`): a band under the image with a
// title and the colour scale, its ends and middle labelled, in a built-in 5x7 pixel font (no font
// library needed for a handful of labels).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lblight/render/volume_render.h"

namespace lblight {

struct Rgb8Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // top row first, 3 bytes per pixel, sRGB
};

// `image` with the band appended below it (same width, taller); letters are drawn upper case,
// characters the font lacks as blanks.
Rgb8Image with_scale_bar(const Rgb8Image& image, const FieldSettings& scale, const std::string& title);

// Draws `text` with its top-left corner at (x, y), each font pixel `size` x `size` image pixels;
// what falls outside the image is clipped. Returns the width drawn.
int draw_text(Rgb8Image& image, int x, int y, const std::string& text, int size, const std::uint8_t colour[3]);
int text_width(const std::string& text, int size);

}  // namespace lblight
