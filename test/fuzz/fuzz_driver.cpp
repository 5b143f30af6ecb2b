// A deterministic random-input driver for libFuzzer-style targets
// (LLVMFuzzerTestOneInput), built with the project's own compiler: no clang
// needed. It runs the seed inputs as given, then N inputs made from them by
// random mutations (bit flips, interesting values, inserted / erased / copied
// ranges, splices, text tokens) and some wholly random ones. A crash (signal,
// sanitizer report, uncaught exception) or an input that runs longer than the
// timeout writes that input to fuzz-<kind>-<target>-<run>.bin and stops the
// run non-zero; `--replay FILE...` runs saved inputs again.
//
//   fuzz_<target> [--runs N] [--seed S] [--max-len BYTES] [--timeout SECONDS]
//                 [--quiet] [SEED_FILE_OR_FOLDER...]
//   fuzz_<target> --replay FILE...
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <random>
#include <string>
#include <thread>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
extern "C" __attribute__((weak)) int LLVMFuzzerInitialize(int* argc, char*** argv);
extern "C" __attribute__((weak)) void __sanitizer_set_death_callback(void (*callback)());

namespace {

using Bytes = std::vector<std::uint8_t>;

// The input being run, for the crash and hang reports (read from signal
// handlers and the watchdog: plain pointers and atomics only).
const std::uint8_t* g_data = nullptr;
std::size_t g_size = 0;
std::atomic<std::uint64_t> g_run{0};
std::atomic<bool> g_running{false};
const char* g_target = "target";

void saveInput(const char* kind) {
  char name[256];
  std::snprintf(name, sizeof(name), "fuzz-%s-%s-%llu.bin", kind, g_target,
                static_cast<unsigned long long>(g_run.load()));
  FILE* f = std::fopen(name, "wb");
  if (f != nullptr) {
    if (g_size > 0) std::fwrite(g_data, 1, g_size, f);
    std::fclose(f);
  }
  std::fprintf(stderr, "\nfuzz: %s on input %llu (%zu bytes), saved to %s; replay: %s --replay %s\n", kind,
               static_cast<unsigned long long>(g_run.load()), g_size, name, g_target, name);
}

void onDeath() {
  if (g_running) saveInput("crash");
}

void onSignal(int sig) {
  if (g_running) saveInput("crash");
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

void installHandlers() {
  if (__sanitizer_set_death_callback != nullptr) __sanitizer_set_death_callback(onDeath);
  for (int sig : {SIGSEGV, SIGABRT, SIGFPE, SIGBUS, SIGILL}) std::signal(sig, onSignal);
}

// Stops the process when one input runs longer than `timeout_s`.
void startWatchdog(double timeout_s) {
  std::thread([timeout_s] {
    std::uint64_t last_run = ~0ull;
    auto since = std::chrono::steady_clock::now();
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      const std::uint64_t run = g_run.load();
      const auto now = std::chrono::steady_clock::now();
      if (run != last_run || !g_running) {
        last_run = run;
        since = now;
      } else if (std::chrono::duration<double>(now - since).count() > timeout_s) {
        saveInput("hang");
        std::fprintf(stderr, "fuzz: input %llu ran longer than %.0f s\n", static_cast<unsigned long long>(run),
                     timeout_s);
        std::_Exit(3);
      }
    }
  }).detach();
}

void runOne(const Bytes& input) {
  // A copy of exactly `size` bytes, so ASan sees reads past its end.
  std::unique_ptr<std::uint8_t[]> copy(new std::uint8_t[std::max<std::size_t>(input.size(), 1)]);
  std::copy(input.begin(), input.end(), copy.get());
  g_data = copy.get();
  g_size = input.size();
  g_running = true;
  LLVMFuzzerTestOneInput(copy.get(), input.size());
  g_running = false;
  ++g_run;
}

Bytes readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  return Bytes(std::istreambuf_iterator<char>(in), {});
}

std::vector<Bytes> readSeeds(const std::vector<std::string>& paths) {
  std::vector<Bytes> seeds;
  for (const auto& path : paths) {
    if (std::filesystem::is_directory(path)) {
      std::vector<std::filesystem::path> files;
      for (const auto& entry : std::filesystem::directory_iterator(path))
        if (entry.is_regular_file()) files.push_back(entry.path());
      std::sort(files.begin(), files.end());  // the same order on every machine
      for (const auto& f : files) seeds.push_back(readFile(f.string()));
    } else {
      seeds.push_back(readFile(path));
    }
  }
  return seeds;
}

// Tokens that matter to text formats (YAML above all); harmless elsewhere.
const std::vector<std::string>& tokens() {
  static const std::vector<std::string> kTokens = {
      ": ",   "- ",    "\n",     "\n  ",   "  ",    "[",      "]",           "{",          "}",
      ",",    "&a ",   "*a",     "<<: *a", "!!",    "!!str ", "!!int ",      "~",          "null",
      "true", "false", "'",      "\"",     "#",     "|",      ">",           "? ",         "0",
      "-1",   "1e999", "-1e999", ".nan",   ".inf",  "-.inf",  "nan",         "2147483648", "-9223372036854775809",
      "0x7f", "1.5",   "[]",     "{}",     "---\n", "...\n",  "%YAML 1.2\n", "\t"};
  return kTokens;
}

class Mutator {
 public:
  Mutator(std::uint64_t seed, std::size_t max_len) : rng_(seed), max_len_(max_len) {}

  Bytes make(const std::vector<Bytes>& seeds) {
    if (seeds.empty() || pick(8) == 0) return random(pick(max_len_ + 1));
    Bytes input = seeds[pick(seeds.size())];
    const std::size_t n = 1 + std::min<std::size_t>(pick(16), pick(16));  // mostly few
    for (std::size_t i = 0; i < n; ++i) mutate(input, seeds);
    if (input.size() > max_len_) input.resize(max_len_);
    return input;
  }

 private:
  std::size_t pick(std::size_t n) { return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }
  std::uint8_t randomByte() { return static_cast<std::uint8_t>(pick(256)); }

  Bytes random(std::size_t n) {
    Bytes b(n);
    for (auto& v : b) v = randomByte();
    return b;
  }

  void mutate(Bytes& b, const std::vector<Bytes>& seeds) {
    static const std::uint8_t kInteresting[] = {0, 1, 2, 0x7f, 0x80, 0xfe, 0xff, '0', '9', '-', '.', ':', '\n'};
    const std::size_t where = pick(b.size() + 1);
    switch (pick(9)) {
      case 0:  // flip a bit
        if (!b.empty()) b[pick(b.size())] ^= static_cast<std::uint8_t>(1u << pick(8));
        break;
      case 1:  // a random byte
        if (!b.empty()) b[pick(b.size())] = randomByte();
        break;
      case 2:  // an interesting byte
        if (!b.empty()) b[pick(b.size())] = kInteresting[pick(sizeof(kInteresting))];
        break;
      case 3: {  // an interesting 16 / 32-bit value
        static const std::uint32_t kWords[] = {0, 1, 0x7fff, 0x8000, 0xffff, 0x7fffffff, 0x80000000, 0xffffffff};
        const std::uint32_t w = kWords[pick(8)];
        const std::size_t len = pick(2) ? 2 : 4;
        if (b.size() >= len) std::memcpy(&b[pick(b.size() - len + 1)], &w, len);
        break;
      }
      case 4: {  // insert random bytes
        const Bytes r = random(1 + pick(8));
        b.insert(b.begin() + where, r.begin(), r.end());
        break;
      }
      case 5:  // erase a range
        if (!b.empty()) {
          const std::size_t from = pick(b.size());
          b.erase(b.begin() + from, b.begin() + from + 1 + pick(std::min<std::size_t>(b.size() - from, 64)));
        }
        break;
      case 6:  // copy a range of itself elsewhere
        if (!b.empty()) {
          const std::size_t from = pick(b.size());
          const Bytes chunk(b.begin() + from, b.begin() + from + 1 + pick(std::min<std::size_t>(b.size() - from, 64)));
          b.insert(b.begin() + pick(b.size() + 1), chunk.begin(), chunk.end());
        }
        break;
      case 7: {  // splice: a range of another seed
        const Bytes& other = seeds[pick(seeds.size())];
        if (!other.empty()) {
          const std::size_t from = pick(other.size());
          const std::size_t len = 1 + pick(std::min<std::size_t>(other.size() - from, 128));
          b.insert(b.begin() + where, other.begin() + from, other.begin() + from + len);
        }
        break;
      }
      default: {  // a token
        const std::string& t = tokens()[pick(tokens().size())];
        b.insert(b.begin() + where, t.begin(), t.end());
        break;
      }
    }
  }

  std::mt19937_64 rng_;
  std::size_t max_len_;
};

[[noreturn]] void usage(const char* why) {
  std::cerr << "fuzz: " << why << "\nusage: " << g_target
            << " [--runs N] [--seed S] [--max-len BYTES] [--timeout SECONDS] [--quiet] [SEED_FILE_OR_FOLDER...]\n"
            << "       " << g_target << " --replay FILE...\n";
  std::exit(2);
}

long long number(const char* option, const char* text) {
  char* end = nullptr;
  const long long v = std::strtoll(text, &end, 10);
  if (end == text || *end != '\0' || v < 0) usage((std::string(option) + " needs a non-negative integer").c_str());
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  g_target = argc > 0 ? argv[0] : "fuzz";
  if (const char* slash = std::strrchr(g_target, '/')) g_target = slash + 1;
  if (LLVMFuzzerInitialize != nullptr) LLVMFuzzerInitialize(&argc, &argv);

  long long runs = 100000, seed = 1, max_len = 4096;
  double timeout_s = 10;
  bool replay = false, quiet = false;
  std::vector<std::string> paths;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) usage((a + " needs a value").c_str());
      return argv[++i];
    };
    if (a == "--runs")
      runs = number("--runs", value());
    else if (a == "--seed")
      seed = number("--seed", value());
    else if (a == "--max-len")
      max_len = number("--max-len", value());
    else if (a == "--timeout")
      timeout_s = static_cast<double>(number("--timeout", value()));
    else if (a == "--replay")
      replay = true;
    else if (a == "--quiet")
      quiet = true;
    else if (a.rfind("--", 0) == 0)
      usage(("unknown option " + a).c_str());
    else
      paths.push_back(a);
  }
  std::vector<Bytes> seeds;
  try {
    seeds = readSeeds(paths);
  } catch (const std::exception& e) {
    usage(e.what());
  }
  if (replay && seeds.empty()) usage("--replay needs input files");

  installHandlers();
  startWatchdog(timeout_s);
  const auto start = std::chrono::steady_clock::now();
  for (const auto& s : seeds) runOne(s);
  if (replay) {
    std::cout << g_target << ": replayed " << seeds.size() << " input(s), no crash\n";
    return 0;
  }
  std::size_t longest = 0;
  for (const auto& s : seeds) longest = std::max(longest, s.size());
  Mutator mutator(static_cast<std::uint64_t>(seed), std::max<std::size_t>(max_len, 2 * longest));
  const long long report_every = std::max(1000ll, runs / 10);
  for (long long r = 0; r < runs; ++r) {
    runOne(mutator.make(seeds));
    if (!quiet && (r + 1) % report_every == 0 && r + 1 < runs)
      std::cout << g_target << ": " << (r + 1) << " inputs" << std::endl;
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << g_target << ": " << (runs + static_cast<long long>(seeds.size())) << " inputs (" << seeds.size()
            << " seeds, mutation seed " << seed << ") in " << static_cast<long long>(s) << " s ("
            << static_cast<long long>((runs + seeds.size()) / std::max(s, 1e-3)) << "/s): no crash, no hang\n";
  return 0;
}
