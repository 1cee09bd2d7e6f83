// Placeholder until its issue lands; replaced by the real command.
#include "app/commands.h"

namespace kdt::app {

void add_scene_command(CLI::App& parent) { (void)parent; }

}  // namespace kdt::app
