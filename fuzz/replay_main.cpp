// A main for a fuzz harness without libFuzzer: runs LLVMFuzzerTestOneInput once on every file
// under the directories (or files) named on the command line, so the seed corpus and every
// input that once crashed a harness replay in a plain gcc build under ctest. A crash, a
// sanitizer report or an abort() in the harness fails the test as it would fail the fuzzer.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace {

std::vector<std::filesystem::path> inputs_under(const std::filesystem::path& root) {
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_regular_file(root)) return {root};
  // A harness with no regression yet has no regressions/ folder (git keeps no empty one).
  if (!std::filesystem::is_directory(root)) return files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
    if (entry.is_regular_file() && entry.path().filename().string().front() != '.')
      files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: " << argv[0] << " DIR_OR_FILE...\n";
    return 2;
  }
  std::size_t count = 0;
  for (int i = 1; i < argc; ++i) {
    for (const auto& file : inputs_under(argv[i])) {
      // Sized read (an istreambuf_iterator loop draws a false -Wnull-dereference from gcc 12).
      // The harness sees each input as libFuzzer would: its own heap buffer, exactly sized, so
      // a read one past the end is an ASan error here too.
      std::vector<std::uint8_t> copy(std::filesystem::file_size(file));
      std::ifstream in(file, std::ios::binary);
      if (!in.read(reinterpret_cast<char*>(copy.data()),
                   static_cast<std::streamsize>(copy.size()))) {
        std::cerr << file.string() << ": cannot read\n";
        return 1;
      }
      LLVMFuzzerTestOneInput(copy.data(), copy.size());
      ++count;
    }
  }
  if (count == 0) {
    std::cerr << "no inputs found under the given paths\n";
    return 1;
  }
  std::cout << count << " inputs replayed without a crash\n";
  return 0;
}
