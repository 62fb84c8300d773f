"""Golden files: what td2adaptor generates and reports, pinned byte for byte.

* `generated/` — the RB-1 example, configured in pyproject.toml (`[tool.td2adaptor]`);
* `tests/golden/cases/<case>/` — one more input each, configured by the case's `td2adaptor.toml` (the project
  configuration format: tds, interfaces, values, backends, package-name, partial) with `output = "expected"`;
  a file a backend copies from its `verbatim/` folder is kept by hash (the manifest's sha256, its source named
  in `.golden-verbatim.txt`), not as a copy; `plugins.txt` installs a plug-in backend for the case;
* `tests/golden/diagnostics/<name>/` — a bad input, the command run on it (`snapshot.toml`) and its output
  (`expected.txt`), paths relative to the snapshot's folder.

`.venv/bin/python -m tests.golden` says what differs; `--refresh` rewrites all of them. A golden diff is
reviewed (`git diff`), never accepted blindly.
"""
