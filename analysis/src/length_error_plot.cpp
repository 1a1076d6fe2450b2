#include "tagsfm/analysis/length_error_plot.h"

#include <sstream>

namespace tagsfm::analysis {

std::string LengthErrorScript(const eval::LengthErrors& lengths, const std::string& title,
                              const std::filesystem::path& image_path) {
  std::ostringstream s;
  s << "# length-measurement error against length (tagsfm evaluate --length-plot)\n"
    << "set terminal pngcairo noenhanced size 800,500 font \"DejaVu Sans,10\"\n"
    << "set output '" << image_path.string() << "'\n"
    << "set title '" << title << "'\nset grid\nset key top left\n"
    << "set xlabel 'true length (m)'\nset ylabel 'length error E = measured - true (mm)'\n"
    << "$pairs << EOD\n";
  bool with_sigma = false;
  for (const eval::LengthError& p : lengths.pairs) {
    const double sigma_mm = p.sigma_m ? *p.sigma_m * 1e3 : 0.0;
    with_sigma = with_sigma || p.sigma_m.has_value();
    s << p.true_length_m << " " << p.error_m * 1e3 << " " << sigma_mm << "\n";
  }
  s << "EOD\nplot 0 with lines lc rgb 'black' notitle";
  if (with_sigma) {
    s << ", $pairs using 1:(2*$3) with points pt 1 ps 0.5 lc rgb '#999999' title '+2 sigma'"
      << ", $pairs using 1:(-2*$3) with points pt 1 ps 0.5 lc rgb '#999999' title '-2 sigma'";
  }
  s << ", $pairs using 1:2 with points pt 7 ps 0.6 lc rgb '#d95f02' title 'tag pairs'\nset output\n";
  return s.str();
}

Result<PlotOutcome> RenderLengthErrorPlot(const eval::LengthErrors& lengths, const std::string& title,
                                          const std::filesystem::path& image_path) {
  return RenderGnuplot([&](const std::filesystem::path& out) { return LengthErrorScript(lengths, title, out); },
                       image_path);
}

}  // namespace tagsfm::analysis
