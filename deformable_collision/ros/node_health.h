#pragma once

#include <diagnostic_updater/DiagnosticStatusWrapper.h>

#include <cstdint>
#include <optional>

namespace deformable_collision {

/// An object's figures over one period of /diagnostics.
struct ObjectPeriod {
  bool has_topic = true;  ///< A robot link has none: tf places it.
  bool in_scene = false;
  /// Its clouds are expected to keep coming: on_cloud other than ignore, or no rest shape yet.
  bool expects_clouds = true;
  std::uint64_t received = 0;  ///< Clouds in the period.
  std::uint64_t dropped = 0;   ///< Of them, dropped (malformed, too large, untransformable).
  std::uint64_t held = 0;      ///< Registrations that held the model in the period.
  std::optional<double> since_last_cloud_s;  ///< Unset before the first cloud.
  double interval_s = 0.0;  ///< Expected between clouds (configured or learned); 0: unknown.
};

/// The cycle's figures over one period of /diagnostics.
struct CyclePeriod {
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;  ///< Cycles longer than 1 / rate_hz.
  /// The 99th percentile of the cloud-to-contacts latency over the latest latency period, if
  /// one ended with clouds since the last status.
  std::optional<double> latency_p99_ms;
  double latency_warn_ms = 100.0;
  double latency_error_ms = 1000.0;
};

/// Fills `status` (level, message, values) for an object:
/// - ERROR: every cloud of the period dropped; or no cloud for 10 expected intervals (and
///   1 s) while its clouds are expected.
/// - WARN: some clouds dropped; no cloud for 3 intervals (and 0.25 s); a registration held
///   the model; no cloud yet; a robot link whose frame tf has not given yet.
/// - OK otherwise.
void objectHealth(const ObjectPeriod& period, diagnostic_updater::DiagnosticStatusWrapper& status);

/// Fills `status` for the cycle: ERROR when more than half the period's cycles overran or
/// the latency's 99th percentile is above latency_error_ms; WARN for any overrun or above
/// latency_warn_ms; OK otherwise.
void cycleHealth(const CyclePeriod& period, diagnostic_updater::DiagnosticStatusWrapper& status);

}  // namespace deformable_collision
