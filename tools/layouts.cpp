// Prints the size, alignment and payload of every generated layout, as the compiler laid
// them out: `cellphys_layouts` for a table, `cellphys_layouts --json` for tools.
#include <cstdio>
#include <cstring>

#include "cellphys/gen/force_table.h"
#include "cellphys/gen/layouts.h"

int main(int argc, char** argv) {
  using namespace cellphys::gen;
  const bool json = argc > 1 && std::strcmp(argv[1], "--json") == 0;
  if (json) {
    std::printf("{\n");
    const int n = static_cast<int>(sizeof kStructTable / sizeof kStructTable[0]);
    for (int i = 0; i < n; ++i) {
      const StructInfo& s = kStructTable[i];
      std::printf("  \"%s\": {\"size\": %u, \"align\": %u, \"payload\": %u}%s\n", s.name, s.size, s.align,
                  s.payload, i + 1 < n ? "," : "");
    }
    std::printf("}\n");
    return 0;
  }
  std::printf("%-34s %6s %6s %8s\n", "layout", "bytes", "align", "payload");
  for (const StructInfo& s : kStructTable) std::printf("%-34s %6u %6u %8u\n", s.name, s.size, s.align, s.payload);
  std::printf("\n%d force types:", kNumForceTypes);
  for (const ForceInfo& f : kForceTable) std::printf(" %s", f.name);
  std::printf("\nSIMD path: %s\n", cellphys::simd::kPathName);
  return 0;
}
