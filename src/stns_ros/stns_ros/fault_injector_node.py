"""fault_injector_node: runs a fault scenario by setting the simulator's parameters.

Triggers are behaviour steps of this run (``run_step`` of /stns/steps) or sim time (/clock, use_sim_time).
Each change goes through the simulator node's SetParameters service, so the simulator's own
validation applies; every change applied (or refused) is published on
/fault_injector/events as JSON. An invalid scenario is refused before anything starts.
"""

from __future__ import annotations

import json

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import String

from stns_ros import topics as T
from stns_ros.driver import dumps
from stns_ros.errors import StnsRosError
from stns_ros.faults import FaultScenario, ScenarioClock, load_scenario, parse_scenario, ramp_points
from stns_ros.params import FAULT_NEUTRAL, NamedRefusals, declare, declare_tuning, result
from stns_ros.runtime import run_node

# On wall time every at_time trigger (seconds since the epoch) would fire at once.
SIM_TIME_NEEDED = ("use_sim_time must be true: at_time triggers and the stamps of "
                   "/fault_injector/events follow the simulator's /clock")


class FaultInjectorNode(NamedRefusals, Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("fault_injector", **kwargs)
        path = declare(self, "scenario", "", "Fault scenario YAML file ('' = no faults).",
                       read_only=True)
        inline = declare(self, "scenario_json", "",
                         "The scenario as JSON (used when 'scenario' is empty).", read_only=True)
        target = declare(self, "sim_node", "rover_sim",
                         "Name of the simulator node whose parameters are set.", read_only=True)
        self.check_period = declare_tuning(self, "fault_injector", "check_period")
        if path:
            self.scenario = load_scenario(path)
        elif inline:
            try:
                self.scenario = parse_scenario(json.loads(inline), "scenario_json")
            except json.JSONDecodeError as e:
                raise StnsRosError(f"scenario_json is not JSON: {e}") from None
        else:
            self.scenario = FaultScenario("none")
        if not self.get_parameter("use_sim_time").value:
            raise StnsRosError(SIM_TIME_NEEDED + "; got use_sim_time false")
        self.add_on_set_parameters_callback(self._validate)
        self.clock_state = ScenarioClock(self.scenario)
        self.values = dict(FAULT_NEUTRAL)
        self.steps = 0
        self.pending: list[tuple[float, dict[str, float], object]] = []  # ramp points
        self.queue: list[tuple[dict[str, float], object, str]] = []
        self.in_flight = False
        self.client = AsyncParameterClient(self, target)
        self.pub = self.create_publisher(String, T.FAULT_EVENTS, 100)
        self.create_subscription(String, T.STEPS, self._on_step, 100)
        self.create_timer(self.check_period, self._check,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"fault scenario {self.scenario.name!r}: "
            + ("; ".join(e.describe() for e in self.scenario.faults) or "no faults"))

    def _validate(self, params: list[Parameter]):
        for prm in params:
            if prm.name == "use_sim_time" and prm.value is not True:
                return result(f"{SIM_TIME_NEEDED}; got {prm.value!r}")
        return result(None)

    def _sim_time(self) -> float:
        return self.get_clock().now().nanoseconds / 1e9

    def _on_step(self, msg: String) -> None:
        try:
            index = int(json.loads(msg.data)["run_step"])
        except (ValueError, KeyError, TypeError):
            return
        self.steps = max(self.steps, index + 1)
        self._check()

    def _check(self) -> None:
        now = self._sim_time()
        for event in self.clock_state.due(self.steps, now):
            if event.kind == "ramp":
                for t, vals in ramp_points(self.values, event, now):
                    self.pending.append((t, vals, event))
                    for name, v in vals.items():
                        self.values[name] = v  # the ramp's end values seed later ramps
            else:
                self.queue.append((event.values, event, event.kind))
                self.values.update(event.values)
        due = [p for p in self.pending if p[0] <= now]
        if due:
            self.pending = [p for p in self.pending if p[0] > now]
            for _, vals, event in due:
                self.queue.append((vals, event, "ramp"))
        self._send()

    def _send(self) -> None:
        if self.in_flight or not self.queue:
            return
        if not self.client.services_are_ready():
            return
        values, event, kind = self.queue.pop(0)
        self.in_flight = True
        params = [Parameter(n, value=float(v)) for n, v in values.items()]
        future = self.client.set_parameters(params)
        future.add_done_callback(lambda f: self._done(f, values, event, kind))

    def _done(self, future, values, event, kind) -> None:
        self.in_flight = False
        response = future.result()
        reasons = [r.reason for r in response.results if not r.successful] if response else [
            "no response"]
        report = {
            "stamp_ns": self.get_clock().now().nanoseconds,
            "step": self.steps,
            "event": event.index,
            "kind": kind,
            "values": values,
            "applied": not reasons,
        }
        if reasons:
            report["reason"] = "; ".join(reasons)
            self.get_logger().error(f"fault {values} refused by the simulator: {report['reason']}")
        else:
            self.get_logger().info(f"fault applied at step {self.steps}: {values}")
        self.pub.publish(String(data=dumps(report)))
        self._send()


def main(args=None) -> None:
    run_node("fault_injector_node", FaultInjectorNode, args)


if __name__ == "__main__":
    main()
