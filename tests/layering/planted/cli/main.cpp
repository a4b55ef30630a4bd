#include "commands.hpp"
#include "force_model/force_model.hpp"
#include "force_model/engine.hpp"
int main() { return predict(); }
