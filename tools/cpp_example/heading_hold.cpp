// A process of one's own, in C++: a "radio" that walks Cassie forward and holds its heading.
//
// It subscribes to the laptop-side state (NETWORK_CASSIE_STATE, robot_state_t) and, at most
// 10 times a second of robot time, publishes a velocity command (COMMAND, command_t): vx as
// given, yaw_rate = -k * yaw, the pelvis yaw from the state's quaternion (q[3..6], w first,
// MuJoCo's order). The types are the stack's own, generated with `cassie types --cpp`.
//
// Build (paths as `cassie types` prints them):
//   g++ -std=c++17 -O2 heading_hold.cpp -I<types>/cpp -I<lcm include> -L<lcm lib> -llcm
//       -Wl,-rpath,<lcm lib> -o heading_hold
// Run beside a launch: ./heading_hold udpm://239.255.76.67:7667 0.3
// (tests/tools/test_cpp_example_commands_the_stack.py builds and runs it against a real bus.)

#include <lcm/lcm-cpp.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>

#include "lcmtypes/command_t.hpp"
#include "lcmtypes/robot_state_t.hpp"

namespace {

constexpr int64_t kCommandPeriodUs = 100000;  // 10 Hz of robot time, as Cassie's radio
constexpr double kYawGain = 1.0;              // rad/s of yaw rate per rad of heading error
constexpr double kMaxYawRate = 0.5;           // rad/s

int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

class HeadingHold {
 public:
  HeadingHold(lcm::LCM* lcm, double vx) : lcm_(lcm), vx_(vx) {}

  void on_state(const lcm::ReceiveBuffer*, const std::string&,
                const lcmtypes::robot_state_t* state) {
    const int64_t utime = state->header.utime;
    if (state->num_positions < 7 || utime - last_sent_us_ < kCommandPeriodUs) return;
    const double w = state->q[3], x = state->q[4], y = state->q[5], z = state->q[6];
    if (!std::isfinite(w + x + y + z)) return;  // never pass a broken state on
    const double yaw = std::atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
    lcmtypes::command_t cmd{};
    cmd.header.utime = utime;
    cmd.header.seq = seq_++;
    cmd.header.send_mono_ns = monotonic_ns();
    cmd.header.source = "heading_hold";
    cmd.vx = vx_;
    cmd.vy = 0.0;
    cmd.yaw_rate = std::fmax(-kMaxYawRate, std::fmin(kMaxYawRate, -kYawGain * yaw));
    cmd.mode = 0;  // walk
    lcm_->publish("COMMAND", &cmd);
    last_sent_us_ = utime;
  }

 private:
  lcm::LCM* lcm_;
  double vx_;
  int64_t last_sent_us_ = -kCommandPeriodUs;
  int64_t seq_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s LCM_URL [VX_M_S [SECONDS]]\n", argv[0]);
    return 2;
  }
  lcm::LCM lcm(argv[1]);
  if (!lcm.good()) {
    std::fprintf(stderr, "cannot open LCM at %s (a multicast route? `ip route add "
                 "224.0.0.0/4 dev lo`)\n", argv[1]);
    return 3;
  }
  const double vx = argc > 2 ? std::atof(argv[2]) : 0.3;
  const double seconds = argc > 3 ? std::atof(argv[3]) : 0.0;  // 0: until killed
  HeadingHold hold(&lcm, vx);
  lcm.subscribe("NETWORK_CASSIE_STATE", &HeadingHold::on_state, &hold);
  std::printf("heading_hold: on %s, vx %.2f m/s\n", argv[1], vx);
  std::fflush(stdout);
  const int64_t end = monotonic_ns() + static_cast<int64_t>(seconds * 1e9);
  while (seconds <= 0.0 || monotonic_ns() < end) {
    if (lcm.handleTimeout(100) < 0) return 1;
  }
  return 0;
}
