"""Topic names and types of the run (the README table mirrors this)."""

CLOCK = "/clock"
GOAL = "/rover/goal"
RANGES = "/rover/obstacle_ranges"
REWARD = "/rover/reward"
ODOM = "/rover/odom"
CMD_VEL = "/cmd_vel"
SITUATION = "/stns/situation"
PLAN = "/stns/plan"
STEPS = "/stns/steps"
SITUATIONS = "/stns/situations"
FAULT_EVENTS = "/fault_injector/events"
RUN_CONFIG = "/stns/run_config"
PARAMETER_EVENTS = "/parameter_events"

TYPES: dict[str, str] = {
    CLOCK: "rosgraph_msgs/msg/Clock",
    GOAL: "geometry_msgs/msg/PointStamped",
    RANGES: "sensor_msgs/msg/LaserScan",
    REWARD: "geometry_msgs/msg/Vector3Stamped",
    ODOM: "nav_msgs/msg/Odometry",
    CMD_VEL: "geometry_msgs/msg/TwistStamped",
    SITUATION: "std_msgs/msg/Int32",
    PLAN: "std_msgs/msg/String",
    STEPS: "std_msgs/msg/String",
    SITUATIONS: "visualization_msgs/msg/MarkerArray",
    FAULT_EVENTS: "std_msgs/msg/String",
    RUN_CONFIG: "std_msgs/msg/String",
    PARAMETER_EVENTS: "rcl_interfaces/msg/ParameterEvent",
}

# Written by the simulator process itself (no DDS hop to the recorder).
SIM_TOPICS = (CLOCK, GOAL, RANGES, REWARD, ODOM, CMD_VEL)
# Low-rate topics of the other nodes, received by the recorder over DDS.
OTHER_TOPICS = (SITUATION, PLAN, STEPS, SITUATIONS, FAULT_EVENTS, PARAMETER_EVENTS)
