"""A user's study never ends in a traceback and nothing finished is lost (issue #11): exit 1
with the missed constraints named and no empty plot for an infeasible study, exit 2 naming the
field for bad input (with the closest key for a typo), relative storage against the study file,
no password in a run folder, Ctrl-C gives 130 and a complete resume command."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from optimizer.cli.main import main
from optimizer.config.study_config import load_study, redact_url
from optimizer.config.yaml_fields import closest, edit_distance
from tests.optimizer.conftest import TINY_OUTER_YAML, TINY_STUDY_YAML

REPO = Path(__file__).resolve().parents[2]


def _run(tmp_path: Path, text: str, *extra: str, name: str = "s.yaml") -> tuple[int, Path]:
    study = tmp_path / name
    study.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    return main(["optimize", str(study), "--out", str(out), *extra]), out


@pytest.mark.parametrize(
    ("text", "field"),
    [
        (TINY_OUTER_YAML.replace("min_link_mass: 0.02}", "min_link_mass: 0.02, min_clearance: 1.5}"),
         "constraints.min_clearance"),
        (TINY_STUDY_YAML.replace("min_link_mass: 0.02}", "min_link_mass: 0.02, min_clearance: 1.5}"),
         "constraints.min_clearance"),
    ],
    ids=["outer", "inner"],
)  # fmt: skip
def test_an_infeasible_study_exits_1_naming_what_was_missed_and_draws_no_plot(tmp_path, capsys, text, field):
    status, out = _run(tmp_path, text.replace("trials: 12", "trials: 8"), "--quiet")
    err = capsys.readouterr().err
    assert status == 1, err
    assert "no feasible design" in err and field in err and "Traceback" not in err
    assert not (out / "front.png").exists()


def test_a_tiny_mass_budget_in_the_outer_search_ends_cleanly(tmp_path, capsys):
    """Shapes the budget cannot build are recorded as missing ``constraints.foot_mass`` (the
    issue's traceback: a negative rod mass); the shapes it can build make the front."""
    text = TINY_OUTER_YAML.replace("min_link_mass: 0.02", "min_link_mass: 0.01, foot_mass: 0.03")
    text = text.replace("toe_segments: [1, 1]", "toe_segments: [1, 2]")
    status, out = _run(tmp_path, text, "--quiet")
    err = capsys.readouterr().err
    assert status in (0, 1) and "Traceback" not in err
    assert (status == 1) == ("constraints.foot_mass" in err)


def test_a_misspelt_key_names_the_closest_one_and_exits_2(tmp_path, capsys):
    status, _ = _run(tmp_path, TINY_STUDY_YAML.replace("min_link_mass", "min_lnk_mas"))
    err = capsys.readouterr().err
    assert status == 2 and "constraints.min_lnk_mas" in err and "did you mean 'min_link_mass'" in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_closest_key_is_within_two_edits():
    assert edit_distance("kitten", "sitting") == 3 and edit_distance("", "ab") == 2
    assert closest("restituton", ("restitution", "speed")) == "restitution"
    assert closest("spede", ("restitution", "speed")) == "speed"  # a swap: 2 edits
    assert closest("velocity_x", ("restitution", "speed")) is None


def test_thousands_of_toes_are_refused_at_once_naming_the_field(tmp_path, capsys):
    started = time.perf_counter()
    status, _ = _run(tmp_path, TINY_STUDY_YAML.replace("toes: [1, 2]", "toes: [1, 5000]"))
    assert status == 2 and "design_space.toes[1]: must be at most" in capsys.readouterr().err
    assert time.perf_counter() - started < 10


def test_a_relative_sqlite_storage_is_found_from_the_study_files_folder(tmp_path, monkeypatch):
    folder = tmp_path / "studies"
    folder.mkdir()
    (folder / "s.yaml").write_text(TINY_STUDY_YAML + "storage: sqlite:///runs/s.db\n", encoding="utf-8")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    config = load_study(folder / "s.yaml")
    assert config.storage == f"sqlite:///{(folder / 'runs' / 's.db').resolve()}"
    assert load_study(folder / "s.yaml").storage == config.storage  # the same from anywhere


def test_a_storage_password_never_reaches_the_run_folder_or_stderr(tmp_path, capsys):
    url = "postgresql://alice:s3cret@localhost:1/footopt"
    assert redact_url(url) == "postgresql://alice:***@localhost:1/footopt"
    status, out = _run(tmp_path, TINY_STUDY_YAML, "--storage", url)
    err = capsys.readouterr().err
    assert status == 2 and "s3cret" not in err and "***" in err
    for f in out.rglob("*") if out.exists() else []:
        assert f.is_dir() or b"s3cret" not in f.read_bytes(), f


def test_quiet_still_says_where_the_results_went_and_trials_with_inner_warns(tmp_path, capsys):
    status, out = _run(tmp_path, TINY_STUDY_YAML, "--quiet", "--trials", "5")
    captured = capsys.readouterr()
    assert status == 0
    assert captured.out.count("\n") == 1 and str(out) in captured.out and "Pareto design" in captured.out
    assert "--trials" in captured.err and "inner" in captured.err


def test_an_internal_error_prints_a_traceback_and_asks_for_a_report(tmp_path, capsys, monkeypatch):
    import optimizer.cli.main as cli

    def broken(args):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(cli, "run_evaluate", broken)
    parser = cli.build_parser
    monkeypatch.setattr(cli, "build_parser", lambda: _with_run(parser(), broken))
    assert main(["evaluate", str(REPO / "configs" / "paper_case2.yaml")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "internal error" in err and "please report it" in err
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "evaluate", str(REPO / "configs" / "paper_case2.yaml")])


def _with_run(parser, run):
    for action in parser._subparsers._group_actions:
        for sub in action.choices.values():
            sub.set_defaults(run=run)
    return parser


def test_sigint_exits_130_quickly_with_a_complete_resume_command(tmp_path):
    """A real Ctrl-C (SIGINT) to ``footopt optimize``: exit 130 within 10 s, the printed resume
    command names the study file, and running it finishes the study."""
    study = tmp_path / "tiny outer.yaml"  # a space: the command must quote it
    study.write_text(TINY_OUTER_YAML.replace("trials: 12", "trials: 400"), encoding="utf-8")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "optimizer", "optimize", str(study), "--out", str(out), "--quiet"]
    proc = subprocess.Popen(command, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not (out / "study.journal").exists():
        time.sleep(0.1)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    sent = time.time()
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert time.time() - sent < 10
    resume = err.split("Resume: ", 1)[1].strip()
    assert "..." not in resume and "'" + str(study) + "'" in resume


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="no POSIX signal masks here")
def test_ctrl_c_while_the_journal_lock_is_held_arrives_after_its_release(tmp_path, tiny_study):
    """Optuna's lock release is not atomic under Ctrl-C (rename, then unlink); the run's lock
    holds SIGINT back while held, so the interrupt arrives after a clean release."""
    from optimizer.results.runs import storage_url

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    storage = storage_url(run_dir, load_study(tiny_study))
    lock = storage._backend._lock
    arrived: list[bool] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: arrived.append(True))
    try:
        lock.acquire()
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
        assert arrived == [] and Path(lock._lock_file).exists()  # held back: the lock is held
        lock.release()
        time.sleep(0.05)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert arrived == [True]  # delivered once, after the release
    assert [p.name for p in run_dir.iterdir()] == ["study.journal"]  # no lock or rename file


def test_a_ctrl_c_inside_a_c_extension_call_is_an_interrupt():
    """A KeyboardInterrupt raised by a signal handler inside a C extension's call (CasADi's DM to
    NumPy conversion) surfaces as SystemError caused by it: footopt treats it as the Ctrl-C it is
    (exit 130), inside the inner search too; other errors stay errors."""
    from optimizer.errors import interrupted
    from optimizer.interrupts import interruptible

    def surfaced() -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as e:
            raise SystemError("<function DM.__array__> returned a result with an exception set") from e

    with pytest.raises(SystemError) as info:
        surfaced()
    assert interrupted(info.value) and not interrupted(SystemError("plain"))
    with pytest.raises(KeyboardInterrupt):
        with interruptible():
            surfaced()
    with pytest.raises(SystemError):
        with interruptible():
            raise SystemError("not an interrupt")


def test_a_ctrl_c_that_a_c_extension_turns_into_another_error_is_an_interrupt():
    """NumPy's comparison of structured arrays (in Optuna's TPE sampler) turned a SIGINT's
    KeyboardInterrupt into ``TypeError: Cannot compare structured arrays ...`` with no cause:
    within :func:`interruptible` any error raised after a SIGINT is the interrupt; before one, a
    TypeError stays a TypeError."""
    from optimizer.interrupts import interruptible

    def swallowed_into_a_type_error() -> None:
        try:
            signal.raise_signal(signal.SIGINT)
        except BaseException:  # noqa: BLE001 - what NumPy's C code does
            pass
        raise TypeError("Cannot compare structured arrays unless they have a common dtype.")

    with pytest.raises(KeyboardInterrupt), interruptible():
        swallowed_into_a_type_error()
    with pytest.raises(TypeError), interruptible():
        raise TypeError("a plain error")


def test_a_ctrl_c_that_casadi_swallows_still_stops_the_outer_search(tiny_outer_study, monkeypatch):
    """A SIGINT whose KeyboardInterrupt is caught on its way (as CasADi's wrapper catches one
    raised in a NumPy conversion while a graph is built) still stops the outer search after that
    batch, its trials marked interrupted; nested blocks keep the outermost handler."""
    import optuna
    from optuna.trial import TrialState

    import optimizer.search.outer as outer
    from optimizer.interrupts import check_interrupt, interruptible

    real = outer.evaluate_designs

    def swallowing(config, designs, *rest):  # noqa: ANN001, ANN002, ANN202
        try:
            signal.raise_signal(signal.SIGINT)
        except BaseException:  # noqa: BLE001 - what the C++ wrapper does
            pass
        return real(config, designs, *rest)

    config = load_study(tiny_outer_study)
    study = outer.open_study(config, optuna.storages.InMemoryStorage())
    outer.run_outer(study, config, 8)  # one batch, not interrupted
    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(outer, "evaluate_designs", swallowing)
    with pytest.raises(KeyboardInterrupt), interruptible(), interruptible():
        outer.run_outer(study, config, 40)
    states = [t.state for t in study.trials]
    assert states.count(TrialState.COMPLETE) == 8 and states.count(TrialState.FAIL) == outer.OUTER_BATCH
    assert all(t.user_attrs.get(outer.ATTR_INTERRUPTED) for t in study.trials if t.state is TrialState.FAIL)
    assert signal.getsignal(signal.SIGINT) is before
    check_interrupt()  # the flag ends with the block


def test_a_ctrl_c_that_casadi_swallows_while_a_landing_is_built_stops_footopt_evaluate(monkeypatch, capsys):
    """``footopt evaluate`` of a whole landing: a SIGINT whose KeyboardInterrupt is caught while
    the landing's functions are built (as CasADi's wrapper may) ends it at its first step (130)."""
    import impulse_core.timedomain.events.run as events_run
    import impulse_core.timedomain.landing_step as landing_step

    real = events_run.landing_function
    built: list[int] = []

    def swallowing(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        try:
            signal.raise_signal(signal.SIGINT)
        except BaseException:  # noqa: BLE001 - what the C++ wrapper does
            pass
        built.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(events_run, "landing_function", swallowing)  # _Landing builds the point's function
    monkeypatch.setattr(landing_step, "landing_function", swallowing)  # step code auto's C or VM function
    before = signal.getsignal(signal.SIGINT)
    assert main(["evaluate", str(REPO / "configs" / "landing_case3.yaml"), "--json"]) == 130
    out = capsys.readouterr()
    assert built and out.out == "" and "footopt: interrupted" in out.err
    assert signal.getsignal(signal.SIGINT) is before


def test_a_ctrl_c_while_footopt_loads_is_an_interrupt(monkeypatch, capsys):
    """The ``footopt`` program loads its command line inside the Ctrl-C guard: an interrupt while
    modules load (or an ImportError an extension raised because of it) exits 130, one line; other
    import errors stay errors. The package itself loads nothing heavy (its names come on use)."""
    import types

    import optimizer
    from optimizer.cli import entry

    class Interrupting(types.ModuleType):
        def __getattr__(self, name: str) -> object:
            raise self.error

    for error, status in ((KeyboardInterrupt(), 130), (ImportError("numpy"), None)):
        if status is None:
            error.__context__ = None
        module = Interrupting("optimizer.cli.main")
        module.error = error
        monkeypatch.setitem(sys.modules, "optimizer.cli.main", module)
        if status is None:
            with pytest.raises(ImportError):
                entry.main()
        else:
            assert entry.main() == status and capsys.readouterr().err.strip() == "footopt: interrupted"
    surfaced = ImportError("PyCapsule_Import could not import module \"datetime\"")
    surfaced.__context__ = KeyboardInterrupt()
    module = Interrupting("optimizer.cli.main")
    module.error = surfaced
    monkeypatch.setitem(sys.modules, "optimizer.cli.main", module)
    assert entry.main() == 130
    assert optimizer.load_model_file.__module__ == "optimizer.config.model_file"
    with pytest.raises(AttributeError):
        optimizer.no_such_name  # noqa: B018
    loaded = subprocess.run([sys.executable, "-c", "import sys, optimizer.cli.entry; print(sorted(sys.modules))"],
                            capture_output=True, text=True, check=True, env={**os.environ, "PYTHONPATH": str(REPO)})
    assert "matplotlib" not in loaded.stdout and "casadi" not in loaded.stdout


def test_the_command_line_exits_130_on_a_surfaced_interrupt(monkeypatch, capsys):
    import optimizer.cli.main as cli

    def run(args):  # noqa: ANN001
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as e:
            raise SystemError("returned a result with an exception set") from e

    monkeypatch.setattr(cli, "run_evaluate", run)
    assert cli.main(["evaluate", "x.yaml"]) == 130
    assert "interrupted" in capsys.readouterr().err


@pytest.mark.skipif(not hasattr(signal, "pthread_kill"), reason="no POSIX signals here")
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # the dropped one, reported
def test_a_ctrl_c_that_something_swallowed_still_ends_the_block():
    """Python drops a KeyboardInterrupt raised inside a weakref callback or ``__del__`` (an
    inner search's worker pool collected as the search ended took one so, and the run finished
    as if no Ctrl-C had come): the block ends with it all the same."""
    import weakref

    from optimizer.interrupts import interruptible

    class Collected:
        pass

    ran: list[bool] = []
    with pytest.raises(KeyboardInterrupt):
        with interruptible():
            thing = Collected()
            weakref.finalize(thing, lambda: ran.append(True) or signal.pthread_kill(threading.get_ident(),
                                                                                    signal.SIGINT))
            del thing  # its callback takes the SIGINT's KeyboardInterrupt, which Python drops
            sum(range(1000))  # the handler runs here, or in the callback
    assert ran == [True]


def test_a_ctrl_c_that_a_caller_answered_is_not_raised_again():
    """``footopt optimize`` catches the interrupt in its block, writes the front and the resume
    command and returns 130: the blocks around it end quietly (once, it was said twice); an
    unanswered one still ends them."""
    from optimizer.interrupts import interrupt_handled, interruptible

    with interruptible():
        try:
            with interruptible():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(1.0)  # the handler raises here
        except KeyboardInterrupt:
            interrupt_handled()
    with pytest.raises(KeyboardInterrupt):
        with interruptible():
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(1.0)
            except KeyboardInterrupt:
                pass  # caught, not answered
