// Configuration of the CAN motion stack (layer 3/4/5): the bus timing, and
// per axis its CANopen node and CiA 402 drive parameters in SI units
// (metres, m/s, m/s^2) with the counts-per-metre scale, plus the simulated
// drive's own settings. Loaded from YAML (config/can_axes.yaml documents
// every field); problems are ConfigErrors naming the field, e.g.
// "axes[1].node_id: duplicate node id 2 (axis 'X' already uses it)".
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace massage_cell::can {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Settings only the simulated drive uses (SimDrive).
struct SimDriveSettings {
  std::string device_name = "massage_cell sim drive";  ///< 0x1008 (segmented SDO upload when > 4 chars)
  double start_position = 0.0;                         ///< m, actual position at power-up
  double home_switch = 0.0;                            ///< m, where the homing switch / index is
  double max_velocity = 1.0;                           ///< m/s, 0x607F max profile velocity
  std::uint32_t device_type = 0x00020192;              ///< 0x1000: CiA 402 servo drive
  /// The axis' mechanics as the simulated motor feels them (SimMechanics: its torque, 0x6077): the true values, which
  /// a force estimate on the master's side only knows approximately. Zero friction, mass and noise: an ideal axis.
  struct Mechanics {
    double screw_lead = 0.0;          ///< m per motor revolution (0: no torque is simulated, 0x6077 stays 0)
    double screw_efficiency = 0.9;    ///< ball screw, 0..1: motor torque = lead F / (2 pi efficiency)
    double moving_mass = 0.0;         ///< kg the motor accelerates (carriage, tool)
    double gravity = 0.0;             ///< m/s^2 pulling toward lower positions (a vertical axis: 9.81)
    double coulomb_friction = 0.0;    ///< N, sliding (nut, seals, guides), against the motion
    double viscous_friction = 0.0;    ///< N s/m
    double friction_stiffness = 1e6;  ///< N/m: the friction's pre-sliding stiffness (Dahl): it reaches its sliding
                                      ///< value after ~coulomb_friction / friction_stiffness of travel, and keeps
                                      ///< its last value at a standstill (what makes a static force hard to read)
    double torque_noise = 0.0;        ///< per mille of the rated torque, RMS, on 0x6077
    std::uint32_t seed = 1;           ///< the noise's
  } mechanics;
};

/// One axis: a CANopen node running a CiA 402 drive.
struct AxisConfig {
  std::string name;               ///< required, unique ("X")
  std::uint8_t node_id = 0;       ///< required, 1..127, unique
  double counts_per_metre = 0.0;  ///< required, > 0
  // CANopen
  std::uint16_t heartbeat_ms = 100;        ///< producer heartbeat time written to 0x1017
  std::uint32_t heartbeat_timeout_ms = 0;  ///< consumer timeout; 0 = 3 x heartbeat_ms
  bool velocity_pdo = false;               ///< map 0x606C (+ 0x6061) into TPDO2
  bool torque_pdo = false;                 ///< map 0x6077 torque actual into TPDO3 (every SYNC)
  double rated_torque = 0.0;               ///< N m, the motor's rated torque (0x6076): 0x6077's 1000 per mille
  // CiA 402 motion
  double profile_velocity = 0.1;         ///< m/s, 0x6081
  double profile_acceleration = 0.5;     ///< m/s^2, 0x6083
  double profile_deceleration = 0.5;     ///< m/s^2, 0x6084
  double quick_stop_deceleration = 2.0;  ///< m/s^2, 0x6085
  int quick_stop_option =
      2;  ///< 0x605A (2: stop on the quick-stop ramp, then switch on disabled; 6: stay in quick stop active)
  double min_position = -1.0;             ///< m, 0x607D:01 software limit
  double max_position = 1.0;              ///< m, 0x607D:02
  double following_error_window = 0.005;  ///< m, 0x6065
  std::uint32_t enable_timeout_ms = 500;  ///< per CiA 402 transition
  std::uint32_t move_timeout_ms = 30000;  ///< profile-position move
  // Homing (0x6098 method, 0x607C offset, 0x6099 speeds)
  int homing_method = 17;                   ///< CiA 402 homing method (17: negative limit switch)
  double home_offset = 0.0;                 ///< m, 0x607C
  double homing_speed = 0.05;               ///< m/s, 0x6099:01 and :02
  std::uint32_t homing_timeout_ms = 10000;  ///< per attempt
  int homing_retries = 2;                   ///< attempts after the first
  SimDriveSettings sim;
  // Consumer of the master's heartbeat in the drive (CiA 301 0x1016; CiA 402
  // 0x6007): 0 = the drive is not told to monitor the master (nothing is
  // written); otherwise 0x1016:01 = master node id << 16 | this time, and
  // 0x6007 = abort_connection_option, are written at start-up. Needs the
  // master's heartbeat (CanConfig::master_heartbeat_ms) to be shorter.
  std::uint32_t master_heartbeat_timeout_ms = 0;
  int abort_connection_option = 1;  ///< 0x6007: 0 no action, 1 fault, 2 disable voltage, 3 quick stop

  std::uint32_t heartbeatTimeoutMs() const { return heartbeat_timeout_ms ? heartbeat_timeout_ms : 3u * heartbeat_ms; }
  /// metres -> counts (rounded), counts -> metres.
  std::int32_t toCounts(double metres) const;
  double toMetres(std::int64_t counts) const { return static_cast<double>(counts) / counts_per_metre; }
};

/// The whole stack.
struct CanConfig {
  std::uint32_t sync_period_us = 10000;  ///< SYNC producer period (bus.sync_period_ms)
  std::uint32_t sdo_timeout_ms = 100;    ///< per SDO frame
  std::uint32_t boot_timeout_ms = 2000;  ///< reset communication -> boot-up
  std::vector<AxisConfig> axes;
  // The master's own CANopen identity (CiA 301 heartbeat producer):
  std::uint8_t master_node_id = 127;        ///< bus.master_node_id: heartbeat COB-ID 0x700 + id; no axis may use it
  std::uint16_t master_heartbeat_ms = 100;  ///< bus.master_heartbeat_ms: producer period; 0 = no heartbeat

  /// The axis with that node id / name, or nullptr.
  const AxisConfig* findNode(std::uint8_t node) const;
  const AxisConfig* findAxis(const std::string& name) const;
};

/// Parses YAML text; `source` names it in error messages. Throws ConfigError.
CanConfig parseCanConfig(const std::string& yaml_text, const std::string& source = "<string>");
/// Loads a YAML file. Throws ConfigError (also for a missing / unreadable file).
CanConfig loadCanConfig(const std::string& path);
/// Checks ranges and uniqueness (parseCanConfig calls it). Throws ConfigError.
void validate(const CanConfig& config, const std::string& source = "<config>");

}  // namespace massage_cell::can
