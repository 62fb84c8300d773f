"""What the dashboard tests share: the `td2adaptor dashboard` command in a child process, headless Chromium
(Debian's `chromium` and `chromedriver`, driven by Selenium), simulated RB-1s behind edge nodes on a real
mosquitto, in this process or in a child one (to be killed)."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tests.conftest import REPO
from tests.runtime.edge import until
from tests.tools import missing

CHROMIUM = next((p for p in (shutil.which("chromium"), "/usr/bin/chromium") if p and os.access(p, os.X_OK)), None)
CHROMEDRIVER = next(
    (p for p in (shutil.which("chromedriver"), "/usr/bin/chromedriver") if p and os.access(p, os.X_OK)), None
)
SERVING = re.compile(r"serving (http://\S+/) ")


def chromium_or_skip() -> tuple[str, str]:
    """The browser and its driver (tests.tools' policy: skipped with the reason here, failed in CI)."""
    if CHROMIUM is None or CHROMEDRIVER is None:
        missing("headless Chromium is not installed (Debian: chromium chromium-driver; .ci/setup-browser.sh)")
    return CHROMIUM, CHROMEDRIVER


class Dashboard:
    """`td2adaptor dashboard --bus URL --listen 127.0.0.1:0 ...` in a child process; `url` once it serves."""

    def __init__(self, bus: str, *args: str, env: Mapping[str, str] | None = None) -> None:
        self.log = tempfile.NamedTemporaryFile(prefix="td2adaptor-dashboard-", suffix=".log", delete=False)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "td2adaptor", "dashboard", "--bus", bus, "--listen", "127.0.0.1:0", *args],
            cwd=REPO,
            env={**os.environ, **(env or {})},
            stdout=self.log,
            stderr=subprocess.STDOUT,
        )
        found = until(lambda: SERVING.search(self.output()) is not None or self.proc.poll() is not None, 30, 0.05)
        match = SERVING.search(self.output())
        assert found and match and self.proc.poll() is None, f"the dashboard did not start:\n{self.output()}"
        self.url = match[1]

    def output(self) -> str:
        return Path(self.log.name).read_text(encoding="utf-8", errors="replace")

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(15)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait(5)

    def close(self) -> None:
        self.stop()
        self.log.close()
        os.unlink(self.log.name)


@contextmanager
def dashboard(bus: str, *args: str, env: Mapping[str, str] | None = None) -> Iterator[Dashboard]:
    d = Dashboard(bus, *args, env=env)
    try:
        yield d
    finally:
        d.close()


@contextmanager
def chromium(performance_log: bool = False) -> Iterator[Any]:
    """A headless Chromium under Selenium (the system's browser and driver: nothing downloaded)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    binary, driver_path = chromium_or_skip()
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--window-size=1400,1000",
    ):
        options.add_argument(arg)
    if performance_log:
        options.set_capability("goog:loggingPrefs", {"performance": "ALL"})
    driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def wait(driver: Any, condition: Callable[[Any], Any], timeout: float = 20.0, what: str = "") -> Any:
    """Until `condition(driver)` is true. An element the page re-rendered between the condition's find and its
    read (stale) is looked for again at the next poll, not a failure (the robots list re-renders on each status)."""
    from selenium.common.exceptions import StaleElementReferenceException, TimeoutException
    from selenium.webdriver.support.ui import WebDriverWait

    try:
        ignored = (StaleElementReferenceException,)
        return WebDriverWait(driver, timeout, poll_frequency=0.05, ignored_exceptions=ignored).until(condition)
    except TimeoutException:
        raise AssertionError(f"timed out waiting for {what or condition}") from None


def css(driver: Any, selector: str) -> list[Any]:
    from selenium.webdriver.common.by import By

    return list(driver.find_elements(By.CSS_SELECTOR, selector))


class RobotProcess:
    """A simulated RB-1 behind its edge node in a child process (`tests.dashboard.robot_proc`), to kill."""

    def __init__(self, url: str, robot: str, env: Mapping[str, str] | None = None) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.dashboard.robot_proc", url, robot],
            cwd=REPO,
            env={**os.environ, **(env or {})},
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line.strip() == "ready", f"the robot process did not start: {line!r}"

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(10)
        if self.proc.stdout:
            self.proc.stdout.close()


def serve_robot(url: str, robot: str, duration: float = 1.0, env: Mapping[str, str] | None = None) -> Any:
    """A simulated RB-1 behind an edge node in this process (`Engine.stop()` ends it)."""
    return serve_sim_robot(url, robot, duration, env)[0]


def serve_sim_robot(url: str, robot: str, duration: float = 1.0, env: Mapping[str, str] | None = None) -> Any:
    """(the edge node's engine, the simulated RB-1 behind it)."""
    from td2adaptor.runtime import RuntimeConfig, serve
    from td2adaptor.runtime.ros.simport import SimPort
    from tests.runtime.rb1 import rb1_model, sim

    model = rb1_model()
    config = RuntimeConfig(robot=robot, bus=url, poll_period=0.05, property_period=0.1, state_dir="")
    robot_sim = sim(duration)
    return serve(model, SimPort(model, robot_sim), config, env=env), robot_sim


def fill(form: Any, values: Mapping[str, str]) -> None:
    """Type `values` into the generated fields named by their JSON pointers."""
    from selenium.webdriver.common.by import By

    for pointer, text in values.items():
        field = form.find_element(By.CSS_SELECTOR, f'[name="{pointer}"]')
        field.clear()
        field.send_keys(text)


def texts(elements: Sequence[Any]) -> list[str]:
    return [e.text for e in elements]
