"""The yardstick of ``bench_ros2_rclpy.py``: the HCR robot's ROS 2 driver as a person writes it by hand.

``python bench/ref_rclpy_driver.py --port PTY [--namespace /x] [--domain-id N] [--rate 10]``, with rclpy
importable (a sourced ROS 2, or Jazzy's wheels made importable: ``bench_ros2_rclpy``'s docstring).

One loop, pyserial, rclpy's typed messages: each sweep writes a read request
for the bumpers, IR, sonar, compass, wheels and environment in turn, waits
for its reply (hcrctl's frame codec), and publishes what ``hcrctl ros2``
publishes of it: a ``sensor_msgs/Range`` per ranger, ``imu``,
``temperature``, ``humidity``, ``joint_states`` and ``odom`` (the wheels
integrated, the yaw the compass's), ``/diagnostics`` once a second. Between
sweeps it spins the node, and a ``cmd_vel`` Twist becomes a velocity frame.
No safety rule: no deadman, no governor, no one-writer rule, no parameters.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import rclpy
import serial
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Quaternion, Twist
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState, Range, RelativeHumidity, Temperature

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame

POLLED = ("bump", "ir", "sonar", "compass", "wheels", "env")
REQUESTS = {C.BY_NAME[name].code: C.encode_request(C.BY_NAME[name]) for name in POLLED}
SONAR = (Range.ULTRASOUND, math.radians(15.0), 0.02, 2.55)
IR = (Range.INFRARED, math.radians(5.0), 0.10, 0.80)
BUMPER = (Range.INFRARED, 0.0, 0.01, 0.01)
WHEEL_BASE, WHEEL_RADIUS = 0.24, 0.035
UNMEASURED = [-1.0] + [0.0] * 8


def quaternion(yaw: float) -> Quaternion:
    return Quaternion(z=math.sin(yaw / 2), w=math.cos(yaw / 2))


class Driver(Node):
    def __init__(self, port: serial.Serial, namespace: str, rate: float) -> None:
        super().__init__("ref_driver", namespace=namespace)
        self.port, self.period = port, 1.0 / rate
        self.decoder = FrameDecoder()
        rangers = [("sonar", 3), ("ir", 5), ("bumper", 3)]
        self.ranges = {
            kind: [
                self.create_publisher(Range, f"range/{kind}_{i}", qos_profile_sensor_data) for i in range(n)
            ]
            for kind, n in rangers
        }
        self.imu = self.create_publisher(Imu, "imu", qos_profile_sensor_data)
        self.temperature = self.create_publisher(Temperature, "temperature", qos_profile_sensor_data)
        self.humidity = self.create_publisher(RelativeHumidity, "humidity", qos_profile_sensor_data)
        self.joints = self.create_publisher(JointState, "joint_states", qos_profile_sensor_data)
        self.odom = self.create_publisher(Odometry, "odom", 10)
        self.diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(Twist, "cmd_vel", self.on_twist, 10)
        self.x = self.y = self.yaw = 0.0
        self.angles = [0.0, 0.0]
        self.signs = (1, 1)
        self.last_wheels: float | None = None
        self.sweeps, self.timeouts, self.next_diagnostics = 0, 0, 0.0

    def on_twist(self, twist: Twist) -> None:
        turn = twist.angular.z * WHEEL_BASE / 2
        left, right = (max(-255, min(255, round((twist.linear.x + s * turn) * 100))) for s in (-1, 1))
        self.port.write(C.encode_request(C.Velocity(left, right)))
        self.signs = (-1 if left < 0 else 1, -1 if right < 0 else 1)

    def ask(self, code: int) -> bytes | None:
        """The reply's content to one read request, or None after 0.1 s."""
        self.port.write(REQUESTS[code])
        deadline = time.monotonic() + 0.1
        while time.monotonic() < deadline:
            for event in self.decoder.feed(self.port.read(self.decoder.wanted)):
                if isinstance(event, Frame) and event.command == code:
                    return event.content
        self.timeouts += 1
        return None

    def sweep(self) -> None:
        stamp = self.get_clock().now().to_msg()
        for code in REQUESTS:
            content = self.ask(code)
            if content is not None:
                self.publish(code, content, stamp)
        self.sweeps += 1

    def publish(self, code: int, content: bytes, stamp: object) -> None:
        name = C.BY_CODE[code].name
        if name == "bump":
            pressed = [bool(content[0] & 1 << i) for i in range(3)]
            self.publish_ranges("bumper", BUMPER, [-math.inf if p else math.inf for p in pressed], stamp)
        elif name == "ir":
            self.publish_ranges("ir", IR, [1020 / v / 100 if v else math.inf for v in content], stamp)
        elif name == "sonar":
            self.publish_ranges("sonar", SONAR, [v / 100 for v in content], stamp)
        elif name == "compass":
            self.yaw = math.remainder(math.radians(90.0 - int.from_bytes(content, "big") / 10), math.tau)
            imu = Imu(orientation=quaternion(self.yaw))
            imu.header.stamp, imu.header.frame_id = stamp, "imu_link"
            imu.orientation_covariance[8] = math.radians(2.0) ** 2
            imu.angular_velocity_covariance = imu.linear_acceleration_covariance = UNMEASURED
            self.imu.publish(imu)
        elif name == "wheels":
            self.publish_wheels(content[0] * self.signs[0] / 100, content[1] * self.signs[1] / 100, stamp)
        elif name == "env":
            temperature = Temperature(temperature=float(content[1] - 256 if content[1] > 127 else content[1]))
            humidity = RelativeHumidity(relative_humidity=content[0] / 100)
            for message, publisher in ((temperature, self.temperature), (humidity, self.humidity)):
                message.header.stamp, message.header.frame_id = stamp, "base_link"
                publisher.publish(message)

    def publish_ranges(
        self, kind: str, spec: tuple[int, float, float, float], values: list, stamp: object
    ) -> None:
        for i, (publisher, value) in enumerate(zip(self.ranges[kind], values, strict=False)):
            radiation, fov, low, high = spec
            message = Range(
                radiation_type=radiation, field_of_view=fov, min_range=low, max_range=high, range=value
            )
            message.header.stamp, message.header.frame_id = stamp, f"{kind}_{i}"
            publisher.publish(message)

    def publish_wheels(self, left: float, right: float, stamp: object) -> None:
        now = time.monotonic()
        dt, self.last_wheels = (now - self.last_wheels if self.last_wheels else 0.0), now
        speed, turn = (left + right) / 2, (right - left) / WHEEL_BASE
        self.x += speed * math.cos(self.yaw) * dt
        self.y += speed * math.sin(self.yaw) * dt
        rates = [left / WHEEL_RADIUS, right / WHEEL_RADIUS]
        self.angles = [a + r * dt for a, r in zip(self.angles, rates, strict=True)]
        joints = JointState(
            name=["left_wheel_joint", "right_wheel_joint"], position=self.angles, velocity=rates
        )
        joints.header.stamp, joints.header.frame_id = stamp, "base_link"
        self.joints.publish(joints)
        odom = Odometry(child_frame_id="base_link")
        odom.header.stamp, odom.header.frame_id = stamp, "odom"
        odom.pose.pose.position.x, odom.pose.pose.position.y = self.x, self.y
        odom.pose.pose.orientation = quaternion(self.yaw)
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = speed, turn
        self.odom.publish(odom)

    def publish_diagnostics(self) -> None:
        status = DiagnosticStatus(name=f"{self.get_fully_qualified_name()}: link", hardware_id=self.port.port)
        status.message = "ok" if not self.timeouts else f"{self.timeouts} timeouts"
        status.level = DiagnosticStatus.OK if not self.timeouts else DiagnosticStatus.WARN
        status.values = [
            KeyValue(key="sweeps", value=str(self.sweeps)),
            KeyValue(key="port", value=self.port.port),
        ]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics.publish(array)

    def run(self) -> None:
        next_sweep = time.monotonic()
        while rclpy.ok(context=self.context):
            self.sweep()
            now = time.monotonic()
            if now >= self.next_diagnostics:
                self.next_diagnostics = now + 1.0
                self.publish_diagnostics()
            next_sweep = max(next_sweep + self.period, now)
            while (left := next_sweep - time.monotonic()) > 0:
                rclpy.spin_once(self, timeout_sec=left)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", required=True)
    parser.add_argument("--namespace", default="")
    parser.add_argument("--domain-id", type=int, default=None)
    parser.add_argument("--rate", type=float, default=10.0)
    args = parser.parse_args()
    rclpy.init(domain_id=args.domain_id)
    with serial.Serial(args.port, 115200, timeout=0.1) as port:
        driver = Driver(port, args.namespace, args.rate)
        print(f"serving {args.port} as {driver.get_fully_qualified_name()}", file=sys.stderr, flush=True)
        try:
            driver.run()
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            port.write(C.encode_request(C.STOP))


if __name__ == "__main__":
    main()
