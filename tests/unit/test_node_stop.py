"""How a node process ends (flip_transport.node_stop): a stop whose KeyboardInterrupt arrives after
the node's loop has already ended (rclpy's wake-up won the race) must not kill the process by SIGINT
(exit -2) or cut its clean-up short. Each case runs in its own interpreter: the cases send SIGINT to
that process, with Python's SIGINT handler set, as the launcher gives every node (a process started
with SIGINT ignored, e.g. from a background job of a non-interactive shell, inherits that and Python
then installs no KeyboardInterrupt handler)."""
import subprocess
import sys
import textwrap

import pytest

PROLOGUE = textwrap.dedent("""
    import os, signal, sys
    from flip_transport.node_stop import run_until_stopped
    signal.signal(signal.SIGINT, signal.default_int_handler)

    def sigint_now():
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(100000):      # bytecodes: the Python handler runs at one of them
            pass

    def close():
        print('close started', flush=True)
        sigint_now()
        print('close finished', flush=True)
""")


def run_case(body):
    return subprocess.run([sys.executable, "-c", PROLOGUE + textwrap.dedent(body)],
                          capture_output=True, text=True, timeout=60)


def test_a_sigint_during_the_clean_up_is_the_stop_already_taken():
    r = run_case("""
        rc = run_until_stopped(lambda: 0, close)     # the loop ended by rclpy's wake-up
        sigint_now()                                 # and one more, on the way to exit
        print('exit', rc, flush=True)
        sys.exit(rc)
    """)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.split() == ["close", "started", "close", "finished", "exit", "0"]


def test_without_it_the_same_sigint_kills_the_process():
    """The case above, with the plain try/finally every rclpy example uses: exit -2 (why it exists)."""
    r = run_case("""
        try:
            rc = 0
        except KeyboardInterrupt:
            rc = 0
        finally:
            close()
        sys.exit(rc)
    """)
    assert r.returncode == -2 and "close finished" not in r.stdout


@pytest.mark.parametrize("loop, rc", [("raise KeyboardInterrupt", 0), ("return 3", 3), ("return None", 0)])
def test_exit_code_and_clean_up(loop, rc):
    r = run_case(f"""
        def loop():
            {loop}
        def quiet_close():
            print('closed', flush=True)
        sys.exit(run_until_stopped(loop, quiet_close))
    """)
    assert r.returncode == rc and r.stdout.split() == ["closed"], r.stdout + r.stderr
