// What the benchmark executables share: a steady clock, peak memory, and CSV files that
// several processes append rows to (scripts/run_benchmarks runs one scene per process).
#pragma once

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace deformable_collision::bench {

using Clock = std::chrono::steady_clock;

inline double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// Peak resident memory of this process so far (Linux reports ru_maxrss in KiB).
inline long peakResidentBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss * 1024L;
}

/// Appends rows to a CSV file, writing `header` first when the file is new or empty.
class CsvAppender {
 public:
  CsvAppender(const std::string& path, const char* header) : file_(std::fopen(path.c_str(), "a")) {
    if (!file_) throw std::runtime_error("cannot open " + path + " for appending");
    std::fseek(file_, 0, SEEK_END);
    if (std::ftell(file_) == 0) std::fprintf(file_, "%s\n", header);
  }
  ~CsvAppender() { std::fclose(file_); }
  CsvAppender(const CsvAppender&) = delete;
  CsvAppender& operator=(const CsvAppender&) = delete;

  std::FILE* file() const { return file_; }

 private:
  std::FILE* file_;
};

}  // namespace deformable_collision::bench
