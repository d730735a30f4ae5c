#pragma once
// FFTW's planner is not thread-safe; every plan creation/destruction in doa/ takes this lock so
// nodes may be constructed from several threads. Executing a plan needs no lock.
#include <mutex>

namespace dronetrack::doa {
std::mutex& fftw_planner_mutex();
}
