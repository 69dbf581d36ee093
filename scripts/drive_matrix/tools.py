"""The tools a drive runs, each in a process group of its own so that a timeout or Ctrl-C can
stop it with all its children, and which of evaluate_slam's newer options this build knows."""
import errno
import os
import shlex
import shutil
import signal
import subprocess
import sys
import threading

from .files import last_log_line

TOOLS = ("simulate_urban", "offline_slam", "evaluate_slam")

# On a Dask worker a tool must not outlive the worker process: a worker that is killed would
# otherwise leave its tool running, writing into the folder that the task's retry cleans and
# fills again. setpriv (util-linux) makes the kernel send SIGKILL to the tool when its parent
# dies; the tool still gets a process group of its own, so timeouts stop it as before.
SETPRIV = shutil.which("setpriv")


class StepFailed(Exception):
    """A step of one drive failed; its message (step, why, the log's last line) goes into the drive's status."""


class Stopped(Exception):
    """The matrix is being stopped (Ctrl-C): the drive gets no row, so a later run resumes it."""


class Context:
    """What every drive needs: tools, folders, options, and the child processes to stop."""

    def __init__(self, bin_dir, config, out, sim_args, keep=False, step_timeout=None,
                 eval_options=(), dump=False, replay_from=None, replay_sets=(), die_with_parent=False):
        self.bin_dir = bin_dir
        self.replay_from = replay_from  # --replay: re-run only the back-ends on FROM's dumps
        self.replay_sets = list(replay_sets)
        self.dump = dump  # offline_slam --dump into each run's slam_*/dump
        self.config = config
        self.out = out
        self.sim_args = sim_args
        self.keep = keep
        self.step_timeout = step_timeout
        self.eval_options = set(eval_options)  # evaluate_slam options this build knows
        self.die_with_parent = die_with_parent  # a tool is killed when the process running it dies
        self._start_local_state()

    def _start_local_state(self):
        """What belongs to this process only: the stop flag and the tools it runs."""
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._procs = set()

    def __getstate__(self):
        # A Dask worker gets a copy of the context: the settings, not this process's children.
        state = dict(self.__dict__)
        for key in ("stopping", "_lock", "_procs"):
            del state[key]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._start_local_state()

    def tool(self, name):
        return os.path.join(self.bin_dir, name)

    def run(self, step, cmd, log_path, stdout_path=None, ok_codes=(0,)):
        """Runs cmd (own process group) with its output in log_path (stdout to stdout_path when
        given); returns its exit status when that is one of ok_codes, else StepFailed names the
        step, the status and the log's last line."""
        if self.stopping.is_set():
            raise Stopped()
        with open(log_path, "ab") as log:
            log.write(("$ %s\n" % " ".join(shlex.quote(c) for c in cmd)).encode())
            log.flush()
            out = open(stdout_path, "wb") if stdout_path else log
            try:
                try:
                    proc = subprocess.Popen(self._launch_prefix(cmd) + list(cmd), stdin=subprocess.DEVNULL,
                                            stdout=out, stderr=log, start_new_session=True)
                except OSError as e:
                    raise StepFailed("%s: cannot start %s: %s" % (step, cmd[0], e.strerror)) from None
                with self._lock:
                    self._procs.add(proc)
                try:
                    code = proc.wait(timeout=self.step_timeout)
                except subprocess.TimeoutExpired:
                    self._stop(proc)
                    raise StepFailed("%s: no result after %g s (stopped)" % (step, self.step_timeout)) from None
                finally:
                    with self._lock:
                        self._procs.discard(proc)
            finally:
                if stdout_path:
                    out.close()
        if self.stopping.is_set():
            raise Stopped()
        if code in ok_codes:
            return code
        tool = os.path.basename(cmd[0])
        last = last_log_line(log_path)
        if code < 0:
            try:
                sig = signal.Signals(-code).name
            except ValueError:
                sig = "signal %d" % -code
            why = "%s crashed (%s)" % (tool, sig)
        else:
            why = "%s exited with status %d" % (tool, code)
        raise StepFailed("%s: %s: %s" % (step, why, last or "(empty log)"))

    def _launch_prefix(self, cmd):
        """setpriv before the tool when it must die with this process; a tool that cannot be
        started fails here as without setpriv (not as setpriv's status 127)."""
        if not (self.die_with_parent and SETPRIV):
            return []
        if os.path.dirname(cmd[0]) and not os.access(cmd[0], os.X_OK):
            code = errno.EACCES if os.path.exists(cmd[0]) else errno.ENOENT
            raise OSError(code, os.strerror(code))
        return [SETPRIV, "--pdeathsig", "KILL", "--"]

    @staticmethod
    def _stop(proc):
        for sig, wait in ((signal.SIGTERM, 5), (signal.SIGKILL, 5)):
            try:
                os.killpg(proc.pid, sig)
            except (ProcessLookupError, PermissionError):
                return
            try:
                proc.wait(timeout=wait)
                return
            except subprocess.TimeoutExpired:
                pass

    def stop_all(self):
        """Stops every running step (only the process groups this script started)."""
        self.stopping.set()
        with self._lock:
            procs = list(self._procs)
        threads = [threading.Thread(target=self._stop, args=(p,)) for p in procs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()


def evaluate_options(bin_dir):
    """Which of the newer evaluate_slam options this build knows (from its usage text)."""
    try:
        p = subprocess.Popen([os.path.join(bin_dir, "evaluate_slam"), "--help"], stdin=subprocess.DEVNULL,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    except OSError:
        return set()
    try:
        text = p.communicate(timeout=30)[0].decode("utf-8", "replace")
    except BaseException:  # a timeout or Ctrl-C: stop its whole group, then go on / re-raise
        Context._stop(p)
        if sys.exc_info()[0] is subprocess.TimeoutExpired:
            return set()
        raise
    return {o for o in ("--run-report", "--loops", "--min-coverage") if o in text}
