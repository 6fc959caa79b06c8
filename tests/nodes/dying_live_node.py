"""A live view that dies during the run (test stand-in for flip_tools.live_node): it says it
listens, as the real one does, then exits 7 without serving anything."""
import sys

print("live: serving ws://127.0.0.1:1", flush=True)
sys.exit(7)
