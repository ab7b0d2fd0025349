// lblight report: error against run time for chosen solutions, against a float64 reference.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <cmath>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "backends/registry.h"
#include "lblight/core/error.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/svg_plot.h"
#include "lblight/pipeline/truth_report.h"
#include "lblight/solve/report.h"

namespace lblight::cli {
namespace {

struct ReportArgs {
  SolveOptions solve;
  std::string output;
  std::string study = "0,6";
  std::vector<std::string> runs;
  std::string channel = "auto";
  bool truth = false;
  double truth_error = 0.02;
};

nlohmann::json finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

const char* kColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

int run_report(const ReportArgs& args) {
  const Scene scene = load_scene(args.solve.scene);
  PlanOverrides ov = args.solve.overrides();
  ov.solutions.reset();  // the report chooses its own solutions (--solutions)
  auto backend = args.solve.make_backend("report");
  auto reference = make_backend({"cpu", args.solve.threads, 0});
  const std::filesystem::path target = output_folder_path(
      args.output.empty() ? std::filesystem::path(std::filesystem::path(args.solve.scene).stem().string() + "-report")
                          : std::filesystem::path(args.output));
  check_scene_output(scene, target);
  StagedDirectory::check_target(target, OutputKind::Report);

  ReportOptions opt;
  opt.solutions = parse_solution_list(args.study, {"--solutions", {}, {}});
  if (args.channel != "auto")
    opt.channel = args.channel == "red" ? 0 : args.channel == "green" ? 1 : 2;
  if (!args.runs.empty()) {
    opt.runs.clear();
    for (const std::string& r : args.runs) {
      const auto colon = r.find(':');
      const std::string method = r.substr(0, colon), prec = colon == std::string::npos ? "float32" : r.substr(colon + 1);
      const auto m = parse_solver_method(method);
      if (!m)
        throw_invalid("--runs '" + r + "': allowed: " + std::string(kSolverMethodNames) +
                      ", optionally :float32/:float64/:float16");
      opt.runs.push_back({*m, parse_precision(prec)});
    }
  } else if (backend->supports(Precision::Float16)) {
    opt.runs.push_back({SolverMethod::Plain, Precision::Float16});
  }
  RunContext ctx = args.solve.run_context();
  ctx.progress = [](const std::string& s) { spdlog::info("{}", s); };
  const BakePlan plan = make_plan(scene, ov, ctx);
  for (const std::string& w : plan.warnings) spdlog::warn("{}", w);
  const Report rep = make_report(plan, *backend, *reference, opt, ctx);

  StagedDirectory dir(target, OutputKind::Report);
  nlohmann::json j;
  j["scene"] = {{"file", scene.file.string()}, {"name", scene.name}, {"hash", scene.hash}};
  j["backend"] = backend->description();
  j["tolerance"] = rep.tolerance;
  j["references"] = nlohmann::json::array();
  for (const auto& r : rep.references)
    j["references"].push_back({{"model", r.model}, {"solution", r.solution}, {"channel", r.channel},
                               {"steps", r.steps}, {"seconds", r.seconds}, {"estimate", finite(r.estimate)}});
  std::ostringstream csv;
  csv << "model,solution,channel,run,step,seconds,true_l2,true_max,estimate_l2,estimate_max\n";
  j["curves"] = nlohmann::json::array();
  Table table({"model", "solution", "run", "steps to tol", "seconds to tol", "bake stops at", "true error there",
               "estimate bounds"});
  for (const ReportCurve& c : rep.curves) {
    nlohmann::json pts = nlohmann::json::array();
    for (const ReportPoint& p : c.points) {
      pts.push_back({p.step, p.seconds, p.true_l2, p.true_max, finite(p.estimate_l2), finite(p.estimate_max)});
      csv << c.model << "," << c.solution << "," << c.channel << "," << c.run << "," << p.step << "," << p.seconds
          << "," << p.true_l2 << "," << p.true_max << "," << (std::isfinite(p.estimate_l2) ? std::to_string(p.estimate_l2) : "")
          << "," << (std::isfinite(p.estimate_max) ? std::to_string(p.estimate_max) : "") << "\n";
    }
    j["curves"].push_back({{"model", c.model}, {"solution", c.solution}, {"channel", c.channel}, {"run", c.run},
                           {"steps_to_tolerance", c.steps_to_tolerance}, {"seconds_to_tolerance", c.seconds_to_tolerance},
                           {"stop_step", c.stop_step}, {"stop_seconds", c.stop_seconds},
                           {"stop_true_l2", c.stop_true_l2}, {"estimate_bounds", c.estimate_bounds},
                           {"worst_true_over_estimate", c.worst_ratio},
                           {"points [step, seconds, true_l2, true_max, estimate_l2, estimate_max]", pts}});
    table.add({c.model, c.solution, c.run, std::to_string(c.steps_to_tolerance), format_seconds(c.seconds_to_tolerance),
               std::to_string(c.stop_step), format_error(c.stop_true_l2), c.estimate_bounds ? "yes" : "no"});
  }
  write_file_atomically(dir.path("report.json"), j.dump(2) + "\n");
  write_file_atomically(dir.path("report.csv"), csv.str());
  // one plot per model and solution: true error solid, estimate dashed, one colour per run
  std::vector<std::string> plots;
  for (const ReportReference& r : rep.references) {
    std::vector<PlotSeries> series;
    int colour = 0;
    for (const ReportCurve& c : rep.curves) {
      if (c.model != r.model || c.solution != r.solution) continue;
      PlotSeries truth{c.run + " true", {}, kColours[colour % 6], false};
      PlotSeries est{c.run + " estimate", {}, kColours[colour % 6], true};
      for (const ReportPoint& p : c.points) {
        truth.points.push_back({p.seconds, p.true_l2});
        est.points.push_back({p.seconds, p.estimate_l2});
      }
      series.push_back(truth);
      series.push_back(est);
      ++colour;
    }
    const std::string name = r.model + "-" + r.solution + ".svg";
    write_file_atomically(dir.path(name),
                          svg_log_plot(scene.name + ": " + r.model + " " + r.solution + " (" + r.channel + ")",
                                       "wall seconds", "relative L2 error of the totals", series));
    plots.push_back(name);
  }
  if (args.truth) {
    TruthReportOptions to;
    to.solutions = opt.solutions;
    to.channel = opt.channel;
    to.truth_error = args.truth_error;
    const TruthReport tr = make_truth_report(scene, ov, *backend, to, ctx);
    nlohmann::json tj;
    tj["truth_error"] = args.truth_error;
    tj["references"] = nlohmann::json::array();
    for (const TruthReference& r : tr.references)
      tj["references"].push_back({{"model", r.model}, {"solution", r.solution}, {"channel", r.channel},
                                  {"seconds", r.seconds}, {"relative_std_error", r.std_error}, {"photons", r.photons}});
    std::ostringstream tcsv;
    tcsv << "model,solution,run,seconds,error_against_truth\n";
    tj["curves"] = nlohmann::json::array();
    Table ttable({"model", "solution", "run", "seconds", "error against light (final)"});
    for (const TruthCurve& c : tr.curves) {
      nlohmann::json pts = nlohmann::json::array();
      for (const auto& p : c.points) {
        pts.push_back({p[0], p[1]});
        tcsv << c.model << "," << c.solution << "," << c.run << "," << p[0] << "," << p[1] << "\n";
      }
      tj["curves"].push_back({{"model", c.model}, {"solution", c.solution}, {"run", c.run},
                              {"points [seconds, relative L2 against the Monte Carlo reference]", pts}});
      if (!c.points.empty())
        ttable.add({c.model, c.solution, c.run, format_seconds(c.points.back()[0]), format_error(c.points.back()[1])});
    }
    write_file_atomically(dir.path("truth.json"), tj.dump(2) + "\n");
    write_file_atomically(dir.path("truth.csv"), tcsv.str());
    for (const TruthReference& r : tr.references) {
      std::vector<PlotSeries> series;
      int colour = 0;
      for (const TruthCurve& c : tr.curves) {
        if (c.model != r.model || c.solution != r.solution) continue;
        PlotSeries s{c.run, {}, kColours[colour++ % 6], false};
        for (const auto& p : c.points) s.points.push_back({p[0], p[1]});
        series.push_back(s);
      }
      const std::string name = r.model + "-" + r.solution + "-truth.svg";
      write_file_atomically(dir.path(name),
                            svg_log_plot(scene.name + ": " + r.model + " " + r.solution + " (" + r.channel +
                                             ") against the Monte Carlo reference (rel. std. error " +
                                             format_error(r.std_error) + ")",
                                         "wall seconds", "relative L2 error against physical light", series, 1e-3));
      plots.push_back(name);
    }
    std::cout << ttable.str() << "against the Monte Carlo reference: wrote truth.json, truth.csv\n";
  }
  dir.commit();
  std::cout << table.str() << "tolerance " << rep.tolerance << "; wrote report.json, report.csv and " << plots.size()
            << " plot(s) to " << target.string() << "\n";
  return 0;
}

}  // namespace

Command add_report_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<ReportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "report",
      "Error against run time: runs chosen solutions of a scene with each solver, compares every check with a "
      "converged float64 reference, and writes report.json, report.csv and one SVG plot per model and solution "
      "(true error solid, the solver's own estimate dashed).");
  args->solve.add_to(*cmd);
  cmd->remove_option(cmd->get_option("--solutions"));
  // Each run goes on until its estimate is below tolerance / depth: a step count does not apply.
  cmd->remove_option(cmd->get_option("--iterations"));
  cmd->add_option("--solutions", args->study, "Base solutions to study (default 0,6: ambient and sun from above)")
      ->check(kNonEmpty)
      ->capture_default_str();
  cmd->add_option("--runs", args->runs,
                  "Runs to compare, as method:precision (default: plain:float32 bicgstab:float32, plus "
                  "plain:float16 on a GPU)");
  cmd->add_option("--channel", args->channel, "Colour channel: auto (the slowest to converge), red, green, blue")
      ->check(CLI::IsMember({"auto", "red", "green", "blue"}))
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output, "Output directory (default: <scene name>-report)")->check(kNonEmpty);
  cmd->add_flag("--truth", args->truth,
                "Also the error against physical light: each studied solution traced by the Monte Carlo reference, "
                "then the papers' and the calibrated LB (every check), CDA and FLD, and another Monte Carlo run at "
                "growing sample counts against it (truth.json, truth.csv, <model>-<solution>-truth.svg)");
  cmd->add_option("--truth-error", args->truth_error, "The reference's relative standard error (with --truth)")
      ->check(finite_range(1e-4, 0.5))
      ->capture_default_str();
  return {cmd, [args] { return run_report(*args); }};
}

}  // namespace lblight::cli
