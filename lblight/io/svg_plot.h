// A small line plot written as SVG (log-scaled y axis), so reports need no plotting package.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace lblight {

struct PlotSeries {
  std::string label;
  std::vector<std::pair<double, double>> points;  // (x, y); y <= 0 or non-finite points are skipped
  std::string color = "#1f77b4";
  bool dashed = false;
};

std::string svg_log_plot(const std::string& title, const std::string& x_label, const std::string& y_label,
                         const std::vector<PlotSeries>& series, double y_floor = 1e-9);

}  // namespace lblight
