#!/usr/bin/env bash
# The project's test command: the no_std core under std (host-tests/) and the host tools (tools/).
# Each crate is built for the machine running cargo (their .cargo/config.toml sets host-tuple).
set -euo pipefail
cd "$(dirname "$0")"
(cd host-tests && cargo test --locked)
(cd tools && cargo test --locked)
