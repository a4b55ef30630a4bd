// Never built by default: the test "the compiler refuses another component's private header"
// builds it and expects the include below to fail.
#include "force_model/engine.hpp"
