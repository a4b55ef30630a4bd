// Built OpenCL programs kept on disk between processes. Every `cutload` command that predicts on
// OpenCL used to hand the kernel source to the driver, and PoCL ran clang's preprocessor over it
// (and over its OpenCL headers) only to find its own cached build; loading the device binary instead
// takes a fraction of that (docs/force_model.md, "Kernels").
//
// An entry carries its whole key (source, build options, platform, device, driver), so a changed
// kernel or driver never loads a stale binary, and a checksum, so a damaged entry is rebuilt and
// replaced. A binary is native code: the cache is used only in a folder the user owns that no one
// else may write to.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace cutload::kernels {

// The folder the cache uses: CUTLOAD_OPENCL_CACHE_DIR, else $XDG_CACHE_HOME/cutload/opencl, else
// $HOME/.cache/cutload/opencl. Empty when the variable says "off", when no home is known, or when
// the folder cannot be made or is not private to this user (owned by another, or group- or
// world-writable); folders it creates are made 0700.
std::optional<std::string> program_cache_dir();

// The entry for `key` in `dir`: its binary, or nothing when absent, damaged, or made for another key.
std::optional<std::vector<unsigned char>> load_program_binary(const std::string& dir, const std::string& key);
// Writes the entry through a temporary file and a rename, so a reader never sees half of one.
// Returns false (and leaves nothing) when it cannot write.
bool store_program_binary(const std::string& dir, const std::string& key, const std::vector<unsigned char>& binary);

// The entry's file name for a key (a hash of it), for tests and for clearing by hand.
std::string program_cache_file(const std::string& dir, const std::string& key);

}  // namespace cutload::kernels
