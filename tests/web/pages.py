"""Waiting on the GUI's page in a browser (Playwright): what the browser tests and
``docs/gui_screenshots.py`` wait for, written once.

The page says where it is through the DOM: a job's state in ``document.body.dataset``
(``plan``, ``analyze``: ``running``, ``done``, ``error``), the acquisition's in the text of
``#acq-status``/``#acq-running``, the Use view's in its dataset (``busy``, and the joints
and wrench of the figures shown, ``shownQ``/``shownW``). Timeouts in ms, as Playwright's.
Plain functions of a Playwright page; this module imports nothing of Playwright.
"""

from __future__ import annotations


def wait_text(page, selector: str, *texts: str, timeout: float = 60_000) -> str:
    """Wait until the text of ``selector`` is one of ``texts``; that text."""
    page.wait_for_function("([sel, texts]) => texts.includes("
                           "document.querySelector(sel)?.textContent)",
                           arg=[selector, list(texts)], timeout=timeout)
    return page.locator(selector).text_content()


def wait_job(page, job: str, *states: str, timeout: float = 60_000) -> str:
    """Wait until ``document.body.dataset[job]`` (``plan``, ``analyze``, ``planview``) is one
    of ``states``; that state."""
    page.wait_for_function("([job, states]) => states.includes(document.body.dataset[job])",
                           arg=[job, list(states)], timeout=timeout)
    return page.evaluate("(job) => document.body.dataset[job]", job)


#: the Use view shows the job's answer for the joints and the wrench set now, and no
#: request is out
_USE_SHOWN = ("() => { const v = document.getElementById('view-use');"
              " return !v.dataset.busy && v.dataset.shownQ === JSON.stringify(useView.poseDeg())"
              " && v.dataset.shownW === JSON.stringify(useView.wrench()); }")


def wait_use_shown(page, timeout: float = 20_000) -> None:
    """Wait until the Use view's figures are those of the pose and wrench now set, then
    again after the page's debounce (150 ms): a request still pending shows as busy."""
    page.wait_for_function(_USE_SHOWN, timeout=timeout)
    page.wait_for_timeout(150)
    page.wait_for_function(_USE_SHOWN, timeout=timeout)


def acquire_dry_run(page, plan: str, out: str, time_scale: float) -> int:
    """In the Acquire view: set the plan, the run's directory and the time scale, take the
    dry run and wait for its motion list; the number of motions listed."""
    page.click("#tab-acquire")
    page.wait_for_selector("#acq-plan", state="visible")
    page.fill("#acq-plan", plan)
    page.fill("#acq-out", out)
    page.fill("#acq-scale", f"{time_scale:g}")
    page.click("#acq-dry")
    page.wait_for_selector("#acq-motions li")
    return page.locator("#acq-motions li").count()
