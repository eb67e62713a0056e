// What a run's timings say about the device rather than the impostors, for flow to print and report.
#pragma once

#include <algorithm>
#include <cstdio>
#include <optional>
#include <span>
#include <string>

namespace bb::cli {

// A sweep's geometry frames do the same work at every threshold (only the impostors' thresholds
// change), so their mean times across the sweep differ by the device's noise alone, or by its
// speed changing within the run. Returns the largest over the smallest (1: steady), 0 where there
// is no positive time.
inline double geometry_spread(std::span<const double> geometry_ms) {
  double lo = 0, hi = 0;
  for (double g : geometry_ms)
    if (g > 0) {
      lo = lo > 0 ? std::min(lo, g) : g;
      hi = std::max(hi, g);
    }
  return lo > 0 ? hi / lo : 0.0;
}

// From this spread on, flow notes that the device's speed changed during the sweep. On this
// project's 2-core machine with llvmpipe the demos' sweeps spread 1.22-1.42 (noise). On the H200 the
// GPU's time for the same geometry grew within a run (fifty-second session: 1.13 ms of GPU work at
// its start, 2-3 ms nine seconds on, whatever the order of the thresholds) and the 1,000-human view
// sweep spread 2.5-2.7, while the impostor frame, the CPU's planning and submission, did not slow:
// the later thresholds' speed-ups flattered the impostors 1.5-2.5x.
inline constexpr double kDriftNoteSpread = 1.6;

// The note for a spread (none under kDriftNoteSpread).
inline std::optional<std::string> drift_note(double spread) {
  if (!(spread >= kDriftNoteSpread)) return std::nullopt;
  char text[320];
  std::snprintf(text, sizeof text,
                "the geometry frames took %.1fx longer at one threshold than at another, for the same work: the "
                "device's speed changed during the sweep, so its speed-ups do not compare; runs of their own "
                "(flow --view/--posture) do",
                spread);
  return std::string(text);
}

}  // namespace bb::cli
