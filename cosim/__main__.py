import signal
import sys

from cosim.cli import main

code = main()
# The interpreter's shutdown (the ray engines' libraries) takes a moment: a Ctrl-C or SIGTERM
# arriving then has nothing left to stop, and must not turn the exit code into a signal's.
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
sys.exit(code)
