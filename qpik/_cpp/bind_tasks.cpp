// Bindings of the tasks layer (qpik._engine.tasks).
#include "bind.hpp"

namespace nb = nanobind;

void bind_tasks(nb::module_& m) {
    (void)m;
}
