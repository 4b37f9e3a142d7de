from setuptools import find_packages, setup

package_name = "rover_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    package_data={package_name: ["py.typed"]},
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},
    zip_safe=True,
    maintainer="STNS team",
    maintainer_email="stns@example.org",
    description="The pybullet differential-drive rover world of the STNS paper: room, goal, obstacle, sensors, behaviours, rewards, faults.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "rover-sim-bench = rover_sim.bench:main",
            "rover-sim-calibrate = rover_sim.calibrate:main",
        ],
    },
)
