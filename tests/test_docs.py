"""The README's and the documentation's examples run and print what the pages say they print;
the set-up commands exist; the parameter, preset and results tables are the package's."""

import contextlib
import doctest
import io
import pathlib
import re

import pytest
from conftest import OFFSCREEN_GL

from qube_suite import baselines, randomization
from qube_suite.devices.qube import parameters

ROOT = pathlib.Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
PAGES = {path.relative_to(ROOT).as_posix(): path.read_text()
         for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]}
OWN_TESTS = {"docs/hardware.md": "test_docs_hardware.py (on the wall-clock test board)",
             "docs/gpu-training.md": "test_mjx.py (with JAX, after every other test)"}
"""Pages whose examples need a board and are run by a test of their own."""
EXAMPLE = re.compile(r"```python\n(.*?)```(?:\n+```text\n(.*?)```)?", re.S)
"""A Python block, and the block of what it prints if one follows it (```text)."""
EXAMPLES = [(page, index, code, output) for page, text in PAGES.items() if page not in OWN_TESTS
            for index, (code, output) in enumerate(EXAMPLE.findall(text))]


def page_text(name):
    return PAGES[f"docs/{name}.md"]


def setup_command(marker):
    match = re.search(rf"<!-- {marker} -->\n```bash\n(.*?)\n```", README, re.S)
    assert match, f"README lacks the {marker}"
    return match.group(1)


def test_two_setup_commands():
    assert "qube-suite demo" in setup_command("demo-command")
    assert "pytest" in setup_command("test-command") and ".[test]" in setup_command("test-command")
    assert len(re.findall(r"<!-- \w+-command -->", README)) == 2


def test_every_page_has_examples_with_checked_output():
    checked = [page for page, _, _, output in EXAMPLES if output]
    assert "README.md" in checked and len(set(checked)) >= 5


@pytest.mark.parametrize(("page", "index", "code", "output"), EXAMPLES,
                         ids=[f"{page}:{index}" for page, index, _, _ in EXAMPLES])
def test_example_runs_and_prints_what_the_page_says(page, index, code, output, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # files the examples write land here
    if "render" in code and not OFFSCREEN_GL:
        pytest.skip("offscreen rendering needs OSMesa (apt-get install libosmesa6)")
    if "my_qube.yaml" in code:  # the calibration pages start from a Qube calibrated on the substitute
        from qube_suite import calibration

        calibration.calibrate("qube_hardware", recording=tmp_path / "experiment.jsonl").save("my_qube.yaml")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, f"{page} python block {index}", "exec"), {})
    if output:
        checker = doctest.OutputChecker()
        flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
        assert checker.check_output(output, printed.getvalue(), flags), (
            f"{page} python block {index} printed:\n{printed.getvalue()}\nthe page says:\n{output}")


def test_parameter_table_matches_the_package():
    rows = re.findall(r"^\| `(\w+)`(?:, `(\w+)`)? \| [^|]+ \| ([^|]+) \|$", page_text("model"), re.M)
    documented = {}
    for first, second, values in rows:
        numbers = [float(n) for n in re.findall(r"[0-9.]+(?:e-?[0-9]+)?", values)]
        for name, number in zip([first, second] if second else [first], numbers, strict=False):
            documented[name] = number
    assert set(documented) >= {"motor_resistance", "pendulum_length", "arm_damping", "gravity"}
    for name, value in documented.items():
        assert parameters.NOMINAL[name] == pytest.approx(value), name


def preset_cell(name, value):
    """A parameter's distribution or an effect's settings as the preset table shows them."""
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
    assert "\n".join(rows) in page_text("randomization")


def test_results_table_covers_every_controller_task_and_domain():
    block = re.search(r"<!-- results:begin -->\n(.*?)<!-- results:end -->", page_text("controllers"), re.S)
    assert block, "docs/controllers.md lacks the results markers"
    header = re.search(r"^\| controller \| task \|.*$", block.group(1), re.M).group(0)
    assert all(f"`{domain}`" in header for domain in ("qube", "qube_hardware"))  # the pendulum's page
    rows = re.findall(r"^\| `(\w+)` \| (\w+) \|", block.group(1), re.M)
    expected = {(name, task) for name, cls in baselines.names().items() for task in cls.tasks}
    assert len(rows) == len(expected) and set(rows) == expected
