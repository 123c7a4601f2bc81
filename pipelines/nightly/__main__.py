"""``python -m pipelines.nightly [DB]``: one night with the defaults, its summary as JSON."""

import json
import sys

from pipelines.nightly.flow import _flow
from pipelines.storage import DEFAULT_DB

print(json.dumps(_flow()(db=sys.argv[1] if len(sys.argv) > 1 else DEFAULT_DB), indent=2, default=str))
