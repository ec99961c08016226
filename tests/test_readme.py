"""The README's examples run, its set-up commands exist, its parameter table is the package's, and
its results table covers every controller, task and domain."""

import pathlib
import re

import pytest
from conftest import OFFSCREEN_GL

from qube_suite import baselines, parameters, randomization, suite

README = (pathlib.Path(__file__).resolve().parent.parent / "README.md").read_text()
PYTHON_BLOCKS = re.findall(r"```python\n(.*?)```", README, re.S)


def setup_command(marker):
    match = re.search(rf"<!-- {marker} -->\n```bash\n(.*?)\n```", README, re.S)
    assert match, f"README lacks the {marker}"
    return match.group(1)


def test_two_setup_commands():
    assert "qube-suite demo" in setup_command("demo-command")
    assert "pytest" in setup_command("test-command") and ".[test]" in setup_command("test-command")
    assert len(re.findall(r"<!-- \w+-command -->", README)) == 2


@pytest.mark.parametrize("index", range(len(PYTHON_BLOCKS)))
def test_python_example_runs(index, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # files the examples write land here
    code = PYTHON_BLOCKS[index]
    if "render" in code and not OFFSCREEN_GL:
        pytest.skip("offscreen rendering needs OSMesa (apt-get install libosmesa6)")
    exec(compile(code, f"README.md python block {index}", "exec"), {})


def test_parameter_table_matches_the_package():
    rows = re.findall(r"^\| `(\w+)`(?:, `(\w+)`)? \| [^|]+ \| ([^|]+) \|$", README, re.M)
    documented = {}
    for first, second, values in rows:
        numbers = [float(n) for n in re.findall(r"[0-9.]+(?:e-?[0-9]+)?", values)]
        for name, number in zip([first, second] if second else [first], numbers, strict=False):
            documented[name] = number
    assert set(documented) >= {"motor_resistance", "pendulum_length", "arm_damping", "gravity"}
    for name, value in documented.items():
        assert parameters.NOMINAL[name] == pytest.approx(value), name


def preset_cell(name, value):
    """A parameter's distribution or an effect's settings as the README's preset table shows them."""
    if name in parameters.PARAMETERS:
        return str(value) if value.relative else f"{value} {parameters.PARAMETERS[name].unit}"
    fields = randomization.EFFECTS[name].fields
    shown = {key: f"[{', '.join(f'{v:g}' for v in setting)}]" if isinstance(setting, tuple)
             else str(setting) if isinstance(setting, randomization.Distribution) else f"{setting:g}"
             for key, setting in value.items()}
    return "; ".join(f"{key} {text} {fields[key].unit}" for key, text in shown.items())


def test_preset_table_matches_the_presets():
    presets = [name for name in randomization.PRESETS if name != "none"]
    configs = [randomization.load(name) for name in presets]
    assert randomization.load("none") == randomization.Randomization()
    rows = ["| | " + " | ".join(f"`{name}`" for name in presets) + " |", "|---" * (len(presets) + 1) + "|"]
    for name in [*parameters.PARAMETERS, *randomization.EFFECTS]:
        entries = [{**config.parameters, **config.effects}.get(name) for config in configs]
        if any(entry is not None for entry in entries):
            cells = ["–" if entry is None else preset_cell(name, entry) for entry in entries]
            rows.append(f"| `{name}` | " + " | ".join(cells) + " |")
    assert "\n".join(rows) in README


def test_results_table_covers_every_controller_task_and_domain():
    block = re.search(r"<!-- results:begin -->\n(.*?)<!-- results:end -->", README, re.S)
    assert block, "README lacks the results markers"
    header = re.search(r"^\| controller \| task \|.*$", block.group(1), re.M).group(0)
    assert all(f"`{domain}`" in header for domain in suite.TASKS_BY_DOMAIN)
    rows = re.findall(r"^\| `(\w+)` \| (\w+) \|", block.group(1), re.M)
    expected = {(name, task) for name, cls in baselines.CONTROLLERS.items() for task in cls.tasks}
    assert len(rows) == len(expected) and set(rows) == expected
