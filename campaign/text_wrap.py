"""Plain text for a person at a terminal's width: lines wrapped at word boundaries with
hanging indentation. Shared by the command line and the jobs that print progress (the
acquisition's panel, the placement search), so neither imports the other."""

from __future__ import annotations


def wrap_text(text: str, width: int | None, hang: int = 2) -> str:
    """``text`` with each line longer than ``width`` wrapped at spaces, never inside a word.

    Continuation lines are indented ``hang`` columns more than their line's own
    indentation, so a wrapped item still reads as one item; ``width`` None
    leaves the text as it is. A word longer than the line stays whole.
    """
    import textwrap

    if not width:
        return text
    out = []
    for line in text.split("\n"):
        if len(line) <= width:
            out.append(line)
            continue
        lead = line[: len(line) - len(line.lstrip())]
        out.extend(textwrap.wrap(line.strip(), width=width, initial_indent=lead,
                                 subsequent_indent=lead + " " * hang, break_long_words=False,
                                 break_on_hyphens=False) or [line])
    return "\n".join(out)


def print_wrapped(console, text: str, style: str | None = None) -> None:
    """Print plain ``text`` (never read as markup) on a rich ``console``, wrapped at word
    boundaries to the console's width with hanging indentation (:func:`wrap_text`)."""
    from rich.text import Text

    # the style on the Text, not on print(): under a live panel, print's style would also
    # colour the panel redrawn after the line
    console.print(Text(wrap_text(text, console.width), style=style or ""), highlight=False,
                  soft_wrap=True)
