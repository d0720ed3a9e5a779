"""`motionlink console` in a real browser (headless Chromium) against an emulated COMPAX drive."""

import time

import pytest

from conftest import SCREENSHOT, Console


def _wait(browser, condition, timeout=10.0, message=""):
    from selenium.webdriver.support.ui import WebDriverWait
    return WebDriverWait(browser, timeout, poll_frequency=0.02).until(condition, message)


def _open(browser, console):
    from selenium.webdriver.common.by import By
    browser.get(console.url)
    _wait(browser, lambda b: b.find_elements(By.CSS_SELECTOR, "#unit-1 .position"), 30, "the drive is found")
    _wait(browser, lambda b: b.find_element(By.CSS_SELECTOR, "#unit-1 .position").text not in ("", "—"),
          10, "its position is shown")
    _wait(browser, lambda b: b.find_element(By.ID, "role").text.startswith("this page controls"), 10, "it controls")


def _position(browser):
    from selenium.webdriver.common.by import By
    text = browser.find_element(By.CSS_SELECTOR, "#unit-1 .position").text
    return float(text.split()[0])


def _start_move(browser, sim, target):
    from selenium.webdriver.common.by import By
    browser.find_element(By.ID, "target").send_keys(str(target))
    browser.find_element(By.ID, "move-speed").send_keys("50")
    browser.find_element(By.ID, "move").click()
    started = sim.wait_event(lambda t: t.startswith(f"drive 1 motion started to {target:.3f}"))
    assert started, f"the move did not start: {sim.events()}"
    return started


def test_positions_change_during_a_move(browser, compax_sim, compax_console):
    _open(browser, compax_console)
    _start_move(browser, compax_sim, 600)
    first = _position(browser)
    _wait(browser, lambda b: _position(b) > first + 1.0, 5, "the shown position follows the move")
    # The plot and the log have had time to fill while the axis moves: the screenshot for the README.
    from selenium.webdriver.common.by import By
    _wait(browser, lambda b: len(b.find_elements(By.CSS_SELECTOR, "#traffic div")) > 60, 10, "the traffic log")
    _wait(browser, lambda b: _position(b) > first + 60.0, 10, "a stretch of the move to plot")
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    assert browser.save_screenshot(str(SCREENSHOT)), SCREENSHOT


def test_stop_halts_the_emulated_axis(browser, compax_sim, compax_console):
    from selenium.webdriver.common.by import By
    _open(browser, compax_console)
    _start_move(browser, compax_sim, 700)
    pressed = time.time()
    browser.find_element(By.ID, "stop").click()
    off = compax_sim.wait_event(lambda t: t == "drive 1 switched off (O0=0)", 5, after=pressed)
    assert off, f"Stop did not stop the drive: {compax_sim.events()}"
    rest = compax_sim.wait_event(lambda t: t.startswith("drive 1 at rest"), 5, after=pressed)
    assert rest, compax_sim.events()
    assert off[0] - pressed < 0.5, f"stopped {off[0] - pressed:.3f} s after the click"
    _wait(browser, lambda b: "Stop pressed" in b.find_element(By.ID, "motion").text, 5, "the page says it stopped")
    # With the report of the confirmed stop (`compax stop --json`), field by field.
    said = browser.find_element(By.ID, "motion").text
    assert "action: stop" in said and "position_units: " in said and "o0: 0" in said, said
    assert "switch the drive on before the next move" in said, said
    # The axis stays where it stopped.
    _wait(browser, lambda b: b.find_element(By.CSS_SELECTOR, "#unit-1 .moving").text == "at rest", 5)


def test_escape_stops_too(browser, compax_sim, compax_console):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys
    _open(browser, compax_console)
    _start_move(browser, compax_sim, 650)
    pressed = time.time()
    ActionChains(browser).send_keys(Keys.ESCAPE).perform()
    off = compax_sim.wait_event(lambda t: t == "drive 1 switched off (O0=0)", 5, after=pressed)
    assert off, f"Escape did not stop the drive: {compax_sim.events()}"


def test_closing_the_tab_during_a_jog_halts_it_within_300_ms(browser, compax_sim, compax_console):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    _open(browser, compax_console)
    console_tab = browser.current_window_handle
    # A second page, read-only, that is told why the jog stopped.
    browser.switch_to.new_window("tab")
    other_tab = browser.current_window_handle
    browser.get(compax_console.url)
    _wait(browser, lambda b: "read-only" in b.find_element(By.ID, "role").text, 10, "the second page is read-only")
    browser.switch_to.window(console_tab)
    jog = browser.find_element(By.ID, "jog-positive")
    ActionChains(browser).click_and_hold(jog).perform()
    started = compax_sim.wait_event(lambda t: t.startswith("drive 1 motion started"))
    assert started, f"the jog did not start: {compax_sim.events()}"
    # Held: the page renews the jog; it still runs well after the 200 ms dead-man time.
    _wait(browser, lambda b: time.time() - started[0] > 0.6, 5)
    assert not any("switched off" in e for e in compax_sim.events()), compax_sim.events()
    closed = time.time()
    browser.close()
    browser.switch_to.window(other_tab)
    off = compax_sim.wait_event(lambda t: t == "drive 1 switched off (O0=0)", 5, after=closed)
    assert off, f"closing the tab did not stop the jog: {compax_sim.events()}"
    assert off[0] - closed < 0.3, f"stopped {off[0] - closed:.3f} s after the tab was closed"
    # Stopped because the page went, not by the dead-man deadline (which alone would stop it too).
    _wait(browser, lambda b: "the page that started it went away" in b.find_element(By.ID, "motion").text, 5,
          "the other page is told the reason")


def test_a_parameter_write_shows_its_read_back(browser, compax_sim, compax_console):
    from selenium.webdriver.common.by import By
    _open(browser, compax_console)
    browser.find_element(By.ID, "param-name").send_keys("P3")
    browser.find_element(By.ID, "param-value").send_keys("4.25")
    browser.find_element(By.ID, "param-write").click()
    _wait(browser, lambda b: "read back" in b.find_element(By.ID, "param-result").text, 10, "the read-back is shown")
    result = browser.find_element(By.ID, "param-result")
    assert result.get_attribute("data-read-back") == "4.25", result.text
    assert "written 4.25" in result.text and "read back 4.25" in result.text, result.text


def _write(browser, name, value):
    from selenium.webdriver.common.by import By
    for field, text in (("param-name", name), ("param-value", value)):
        browser.find_element(By.ID, field).clear()
        browser.find_element(By.ID, field).send_keys(text)
    browser.find_element(By.ID, "param-write").click()
    _wait(browser, lambda b: b.find_element(By.ID, "param-result").text.startswith(f"{name} ("), 10,
          f"the write of {name} is answered")
    return browser.find_element(By.ID, "param-result")


def test_a_powercube_write_shows_the_report_of_the_command_line(browser):
    console = Console("powercube", "--port", "sim", "--modules", "1")
    try:
        _open(browser, console)
        # The report of `motionlink powercube set MaxVel 0.8 --json`, field by field; the module's float to the
        # digits it has, in the unit the parameter list gives.
        result = _write(browser, "MaxVel", "0.8")
        assert "MaxVel (72) written 0.8 rad/s, read back 0.8 rad/s" in result.text, result.text
        assert "verified: true" in result.get_attribute("title"), result.get_attribute("title")
        # TargetVel cannot be read: the library checks it against its twin in ticks and reports it in rad/s.
        result = _write(browser, "TargetVel", "0.5")
        assert "TargetVel (79) written 0.5 rad/s, read back 0.5" in result.text, result.text  # 0.500001: from ticks
        assert abs(float(result.get_attribute("data-read-back")) - 0.5) < 1e-3, result.text
    finally:
        console.stop()


def test_the_error_table_puts_codes_and_meanings_in_their_columns(browser, compax_sim, compax_console):
    from selenium.webdriver.common.by import By
    _open(browser, compax_console)
    browser.find_element(By.ID, "errors-read").click()
    _wait(browser, lambda b: len(b.find_elements(By.CSS_SELECTOR, "#errors tbody tr")) == 8, 10, "S18's entries")
    cells = [c.text for c in browser.find_elements(By.CSS_SELECTOR, "#errors tbody tr:first-child td")]
    assert cells[0] == "newest", cells
    assert cells[1] == "99", f"the code in the Code column: {cells}"
    assert cells[2] == "the error before was acknowledged", f"the meaning in the Meaning column: {cells}"


def test_a_wrong_token_is_refused(browser, compax_sim, compax_console):
    from selenium.webdriver.common.by import By
    browser.get(f"{compax_console.base}/?token=0123456789abcdef0123456789abcdef")
    body = browser.find_element(By.TAG_NAME, "body").text
    assert "wrong or missing token" in body, body
    assert not browser.find_elements(By.ID, "stop"), "no page without the token"
    browser.get(f"{compax_console.base}/")
    assert "wrong or missing token" in browser.find_element(By.TAG_NAME, "body").text


def test_a_second_page_is_read_only_and_says_so(browser, compax_sim, compax_console):
    from selenium.webdriver.common.by import By
    _open(browser, compax_console)
    browser.switch_to.new_window("tab")
    browser.get(compax_console.url)
    _wait(browser, lambda b: "read-only" in b.find_element(By.ID, "role").text, 10, "the second page is told")
    assert not browser.find_element(By.ID, "move").is_enabled()
    assert not browser.find_element(By.ID, "jog-positive").is_enabled()
    assert browser.find_element(By.ID, "stop").is_enabled(), "Stop works on every page"



@pytest.mark.parametrize("family,label,unit", [("scu", "A1", "counts"), ("powercube", "module 1", "rad"),
                                               ("compax", "drive 1", "units")])
def test_each_family_shows_its_units_live(browser, family, label, unit):
    from selenium.webdriver.common.by import By
    console = Console(family, "--port", "sim")
    try:
        _open(browser, console)
        row = browser.find_element(By.ID, "unit-1")
        assert label in row.text, row.text
        assert browser.find_element(By.CSS_SELECTOR, "#unit-1 .position").text.endswith(unit)
        _wait(browser, lambda b: int(b.find_element(By.ID, "rate").text.split()[0]) >= 20, 10,
              "samples at 20 Hz or more")
    finally:
        console.stop()


def _unit_name(browser):
    from selenium.webdriver.common.by import By
    return browser.find_element(By.ID, "control-unit").text


@pytest.mark.parametrize("family,args,first", [("scu", (), "actuator A1"),
                                                ("powercube", ("--modules", "1,2,3"), "module 1"),
                                                ("compax", (), "drive 1")])
def test_at_1280_px_no_column_is_cut_and_the_move_panel_names_its_unit(browser, family, args, first):
    from selenium.webdriver.common.by import By
    browser.set_window_size(1280, 800)
    console = Console(family, "--port", "sim", *args)
    try:
        _open(browser, console)
        assert browser.execute_script("return window.innerWidth") == 1280
        _wait(browser, lambda b: len(b.find_elements(By.CSS_SELECTOR, "#params tbody button")) >= 3, 10,
              "the parameter table")
        # Every button of the parameter table lies wholly inside the page's width and inside its section, and
        # no table of the page is wider than its section (nothing hidden behind a scroll bar).
        cut = browser.execute_script("""
            const page = document.documentElement.clientWidth;
            const out = [];
            for (const b of document.querySelectorAll('#params button')) {
              const r = b.getBoundingClientRect(), s = b.closest('section').getBoundingClientRect();
              if (r.width <= 0 || r.left < Math.max(0, s.left) || r.right > Math.min(page, s.right))
                out.push(`${b.getAttribute('aria-label') || b.textContent}: ${r.left}..${r.right} in ${s.left}..${s.right}`);
            }
            for (const t of document.querySelectorAll('main table')) {
              const s = t.closest('section');
              if (s.scrollWidth > s.clientWidth) out.push(`#${t.id}: ${s.scrollWidth} px in ${s.clientWidth} px`);
            }
            return out;
        """)
        assert cut == [], cut
        # The Move panel (and the parameters and the error history) name the unit they act on.
        assert _unit_name(browser) == first
        assert browser.find_element(By.ID, "params-unit").text == first
        assert first in browser.find_element(By.ID, "move").text
    finally:
        console.stop()


def test_each_of_three_modules_is_selected_named_and_moved_alone(browser):
    from selenium.webdriver.common.by import By
    console = Console("powercube", "--port", "sim", "--modules", "1,2,3")
    try:
        _open(browser, console)
        rows = browser.find_elements(By.CSS_SELECTOR, "#units tbody tr")
        assert [r.get_attribute("id") for r in rows] == ["unit-1", "unit-2", "unit-3"]
        _wait(browser, lambda b: all(b.find_element(By.CSS_SELECTOR, f"#unit-{n} .position").text not in ("", "—")
                                     for n in (1, 2, 3)), 10, "the three positions")
        browser.find_element(By.ID, "pick-2").click()
        _wait(browser, lambda b: _unit_name(b) == "module 2", 5, "the Move panel names module 2")
        browser.find_element(By.ID, "target").send_keys("0.6")
        browser.find_element(By.ID, "move-speed").send_keys("1")
        browser.find_element(By.ID, "move").click()
        _wait(browser, lambda b: "module 2" in b.find_element(By.ID, "motion").text
              and "running" not in b.find_element(By.ID, "motion").text, 20, "the move of module 2 ends")

        def position(n):
            return float(browser.find_element(By.CSS_SELECTOR, f"#unit-{n} .position").text.split()[0])
        _wait(browser, lambda b: abs(position(2) - 0.6) < 0.01, 5, "module 2 is at its target")
        assert abs(position(1) - 0.6) > 0.1 and abs(position(3) - 0.6) > 0.1, "the others stay where they were"
    finally:
        console.stop()


def _record_sent(browser):
    """From now on, each message the page sends (but the jog's renewals) is kept in `window.__sent`."""
    browser.execute_script("""
        window.__sent = [];
        const send = WebSocket.prototype.send;
        WebSocket.prototype.send = function (data) {
          if (!String(data).includes('"jog_hold"')) window.__sent.push(JSON.parse(data));
          return send.call(this, data);
        };
    """)


def test_an_unreadable_jog_speed_is_refused_on_the_page_and_nothing_is_sent(browser, compax_sim, compax_console):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    _open(browser, compax_console)
    _record_sent(browser)
    speed = browser.find_element(By.ID, "jog-speed")
    # Text a number input cannot read: its `value` is "" as that of an empty field (was: sent as no speed).
    speed.send_keys("1e")
    assert browser.execute_script("return document.getElementById('jog-speed').value") == ""
    jog = browser.find_element(By.ID, "jog-positive")
    ActionChains(browser).click_and_hold(jog).perform()
    _wait(browser, lambda b: "refused (jog)" in b.find_element(By.ID, "motion").text, 5, "the page refuses the jog")
    ActionChains(browser).release(jog).perform()
    said = browser.find_element(By.ID, "motion").text
    assert "jog speed: what is typed is not a number" in said and "nothing was sent" in said, said
    assert "failed" in browser.find_element(By.ID, "motion").get_attribute("class")
    sent = browser.execute_script("return window.__sent")
    assert not [m for m in sent if m["type"] == "jog"], sent
    assert not any(e for e in compax_sim.events() if "motion started" in e), compax_sim.events()
    # Corrected, the same button jogs at the speed typed.
    speed.clear()
    speed.send_keys("20")
    ActionChains(browser).click_and_hold(jog).perform()
    started = compax_sim.wait_event(lambda t: t.startswith("drive 1 motion started"))
    ActionChains(browser).release(jog).perform()
    assert started, f"the jog did not start: {compax_sim.events()}"
    jogs = [m for m in browser.execute_script("return window.__sent") if m["type"] == "jog"]
    assert jogs == [{"type": "jog", "direction": "positive", "drive": 1, "speed": 20}], jogs


@pytest.mark.parametrize("family,move,jog", [
    ("scu", "Speed (%; empty: 100 %)", "Jog speed (%; empty: the unit's remote_speed_f1 as it is)"),
    ("powercube", "Speed (rad/s; empty: the module's TargetVel as it is)",
     "Jog speed (rad/s; empty: the module's TargetVel as it is)"),
    ("compax", "Speed (%; empty: the drive's SPEED setting as it is)",
     "Jog speed (%; empty: the drive's SPEED setting as it is)"),
])
def test_the_speed_labels_say_what_an_empty_speed_does_in_each_family(browser, family, move, jog):
    from selenium.webdriver.common.by import By
    console = Console(family, "--port", "sim")
    try:
        _open(browser, console)
        assert browser.find_element(By.CSS_SELECTOR, "label[for=move-speed]").text == move
        assert browser.find_element(By.CSS_SELECTOR, "label[for=jog-speed]").text == jog
    finally:
        console.stop()
