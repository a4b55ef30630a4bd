#include "engine.hpp"
#include "cli/commands.hpp"
int predict() { return 0; }
