"""Reading PlDoc comments for `ita kb list`."""

from __future__ import annotations

from pathlib import Path

from ita.logic.pldoc import doc_comments


def test_mode_line_and_first_sentence(tmp_path: Path):
    source = tmp_path / "m.pl"
    source.write_text(
        "%!  pick(+Tool, -Slot, [+Opt]) is det.\n"
        "%!  pick(+Tool) is det.\n"
        "%\n"
        "%   Pick Tool (e.g. a probe) from\n"
        "%   its slot. More text.\n"
        "%\n"
        "%   @error domain_error(tool, Tool)\n"
        "pick(_, _, _).\n"
        "% plain comment\n"
        "%!  ready is semidet\n"
        "ready.\n",
        encoding="utf-8",
    )
    docs = doc_comments(source)
    assert docs[("pick", 3)].summary == "Pick Tool (e.g. a probe) from its slot."
    assert docs[("pick", 3)].mode == "pick(+Tool, -Slot, [+Opt]) is det."
    assert docs[("pick", 1)].summary == "Pick Tool (e.g. a probe) from its slot."
    assert docs[("ready", 0)].summary == ""
    assert set(docs) == {("pick", 3), ("pick", 1), ("ready", 0)}
