"""Pages generated at every ``mkdocs build`` (run by the mkdocs-gen-files plugin).

- ``index.md``: the README, its links rewritten from the repository root to ``docs/``;
- ``api/*.md``: the API reference of the science packages (:mod:`gen_api`);
- ``config-reference.md``: every key of every scenario kind (:mod:`gen_config_reference`);
- ``gallery.md``: the example scripts and their figures (:mod:`gen_gallery`);
- the changelog, the licence and the citation file, which the README links to.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
sys.path.insert(0, str(ROOT))

import gen_api  # noqa: E402
import gen_config_reference  # noqa: E402
import gen_gallery  # noqa: E402


def home_page(readme: str) -> str:
    """The README as the site's home page: links into ``docs/`` made relative to it."""
    return re.sub(r"\]\(docs/", "](", readme)


def main() -> None:
    """Write every generated page into the build."""
    with mkdocs_gen_files.open("index.md", "w") as f:
        f.write(home_page((ROOT / "README.md").read_text(encoding="utf-8")))
    mkdocs_gen_files.set_edit_path("index.md", "../README.md")
    for name in ("CHANGELOG.md", "LICENSE", "CITATION.cff"):
        with mkdocs_gen_files.open(name, "w") as f:
            f.write((ROOT / name).read_text(encoding="utf-8"))

    pages = gen_api.api_pages(ROOT)
    with mkdocs_gen_files.open("api/index.md", "w") as f:
        f.write(gen_api.api_index(pages))
    for page in pages:
        with mkdocs_gen_files.open(f"api/{page.package}.md", "w") as f:
            f.write(page.markdown())

    with mkdocs_gen_files.open("config-reference.md", "w") as f:
        f.write(gen_config_reference.config_reference(ROOT))
    with mkdocs_gen_files.open("gallery.md", "w") as f:
        f.write(gen_gallery.gallery_page(ROOT))


main()
