#pragma once
// Output locations, checked before the work that fills them: a diagnosis or a training run of
// minutes must not end in "cannot write", nor a filesystem exception escape as an internal error.
#include <string>

namespace crowdmpm {

// Creates the folder `dir` (with its parents) and writes and removes a probe file in it. Throws
// Error "<dir>: cannot ... (<reason>)" when the folder cannot be made (a file in the way, a
// read-only or missing parent) or takes no new file. `what` names the option in messages.
void prepare_output_folder(const std::string& dir, const std::string& what = "output folder");

// The output file `path`: not a folder, and its folder exists and takes a new file (probed as
// above; the file itself is not created). Throws Error naming the path and the reason.
void check_output_file(const std::string& path, const std::string& what = "output file");

}  // namespace crowdmpm
