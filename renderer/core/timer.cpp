#include "renderer/core/timer.h"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

namespace kdt {
namespace {

size_t read_status_kb(const char* key) {
    std::ifstream in("/proc/self/status");
    std::string line;
    size_t keylen = std::strlen(key);
    while (std::getline(in, line)) {
        if (line.compare(0, keylen, key) == 0) return std::stoull(line.substr(keylen + 1)) * 1024;
    }
    return 0;
}

}  // namespace

size_t peak_rss_bytes() { return read_status_kb("VmHWM"); }
size_t current_rss_bytes() { return read_status_kb("VmRSS"); }

void reset_peak_rss() {
    if (FILE* f = std::fopen("/proc/self/clear_refs", "w")) {
        std::fputs("5", f);
        std::fclose(f);
    }
}

}  // namespace kdt
