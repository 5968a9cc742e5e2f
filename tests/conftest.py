import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
# the tests use their own model cache, never the user's
os.environ["MULTIPOLE_CACHE"] = tempfile.mkdtemp(prefix="multipole-test-cache-")
