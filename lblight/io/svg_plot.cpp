#include "lblight/io/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace lblight {

namespace {
std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else out += c;
  }
  return out;
}
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}
}  // namespace

std::string svg_log_plot(const std::string& title, const std::string& x_label, const std::string& y_label,
                         const std::vector<PlotSeries>& series, double y_floor) {
  const double W = 760, H = 460, left = 80, right = 230, top = 40, bottom = 60;
  double x_max = 0, y_min = 1e300, y_max = 0;
  for (const PlotSeries& s : series)
    for (auto [x, y] : s.points) {
      if (!(y > 0) || !std::isfinite(y) || !std::isfinite(x)) continue;
      x_max = std::max(x_max, x);
      y_min = std::min(y_min, std::max(y, y_floor));
      y_max = std::max(y_max, y);
    }
  if (y_max <= 0) y_min = y_floor, y_max = 1;
  const double lo = std::floor(std::log10(y_min)), hi = std::ceil(std::log10(y_max));
  const double decades = std::max(1.0, hi - lo);
  if (x_max <= 0) x_max = 1;
  const double pw = W - left - right, ph = H - top - bottom;
  auto px = [&](double x) { return left + pw * x / x_max; };
  auto py = [&](double y) { return top + ph * (hi - std::log10(std::max(y, y_floor))) / decades; };

  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << W / 2 << "\" y=\"22\" text-anchor=\"middle\" font-size=\"14\">" << escape(title) << "</text>\n";
  // grid and axes
  for (int d = 0; d <= static_cast<int>(decades); ++d) {
    const double y = top + ph * d / decades;
    o << "<line x1=\"" << left << "\" y1=\"" << num(y) << "\" x2=\"" << left + pw << "\" y2=\"" << num(y)
      << "\" stroke=\"#ddd\"/>\n";
    o << "<text x=\"" << left - 6 << "\" y=\"" << num(y + 4) << "\" text-anchor=\"end\">1e" << static_cast<int>(hi) - d
      << "</text>\n";
  }
  for (int t = 0; t <= 5; ++t) {
    const double xv = x_max * t / 5, x = px(xv);
    char lbl[32];
    std::snprintf(lbl, sizeof lbl, x_max < 10 ? "%.2f" : "%.0f", xv);
    o << "<line x1=\"" << num(x) << "\" y1=\"" << top << "\" x2=\"" << num(x) << "\" y2=\"" << top + ph
      << "\" stroke=\"#eee\"/>\n";
    o << "<text x=\"" << num(x) << "\" y=\"" << top + ph + 16 << "\" text-anchor=\"middle\">" << lbl << "</text>\n";
  }
  o << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << pw << "\" height=\"" << ph
    << "\" fill=\"none\" stroke=\"black\"/>\n";
  o << "<text x=\"" << left + pw / 2 << "\" y=\"" << H - 18 << "\" text-anchor=\"middle\">" << escape(x_label)
    << "</text>\n";
  o << "<text transform=\"translate(18," << top + ph / 2 << ") rotate(-90)\" text-anchor=\"middle\">"
    << escape(y_label) << "</text>\n";
  // series and legend
  int row = 0;
  for (const PlotSeries& s : series) {
    std::string path;
    for (auto [x, y] : s.points) {
      if (!(y > 0) || !std::isfinite(y) || !std::isfinite(x)) continue;
      path += (path.empty() ? "M" : " L") + num(px(x)) + "," + num(py(y));
    }
    if (!path.empty())
      o << "<path d=\"" << path << "\" fill=\"none\" stroke=\"" << s.color << "\" stroke-width=\"1.8\""
        << (s.dashed ? " stroke-dasharray=\"6,4\"" : "") << "/>\n";
    const double ly = top + 10 + 18 * row++;
    o << "<line x1=\"" << left + pw + 12 << "\" y1=\"" << ly << "\" x2=\"" << left + pw + 40 << "\" y2=\"" << ly
      << "\" stroke=\"" << s.color << "\" stroke-width=\"2\"" << (s.dashed ? " stroke-dasharray=\"6,4\"" : "")
      << "/>\n";
    o << "<text x=\"" << left + pw + 46 << "\" y=\"" << ly + 4 << "\">" << escape(s.label) << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

}  // namespace lblight
