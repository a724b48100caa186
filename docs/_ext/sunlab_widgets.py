"""Widgets on the site without a kernel or a CDN: the saved widget state drawn as static HTML.

A notebook executed at build time saves its widgets' state (nbclient's ``store_widget_state``);
myst-nb would draw them with ipywidgets' JavaScript from a CDN, which an offline reader (and
this build machine) cannot reach. Here each widget view becomes plain HTML from that state:
boxes and grids as CSS flex and grid, buttons with their colours, the images and HTML of
``Output`` and ``HTML`` widgets, and sliders, dropdowns and toggles as their current values,
disabled. The page shows the explorer as the notebook left it; it does not respond to clicks.
"""

from __future__ import annotations

import html
import json

#: ``Layout`` traits copied to CSS (ipywidgets names them as CSS with ``_`` for ``-``)
LAYOUT_CSS = ("width", "height", "min_width", "max_width", "min_height", "max_height",
              "margin", "padding", "border", "overflow", "flex", "flex_flow", "align_items",
              "justify_content", "grid_gap", "grid_template_columns", "grid_template_rows",
              "grid_template_areas", "grid_area", "display", "visibility")
BOXES = {"HBoxModel": "row", "VBoxModel": "column", "BoxModel": "row"}


def _model(state: dict, ref) -> dict | None:
    if isinstance(ref, str) and ref.startswith("IPY_MODEL_"):
        return state.get(ref[len("IPY_MODEL_"):])
    return None


def _css(state: dict, model: dict, extra: dict | None = None) -> str:
    layout = (_model(state, model["state"].get("layout")) or {"state": {}})["state"]
    css = dict(extra or {}) | {t.replace("_", "-"): layout[t] for t in LAYOUT_CSS if layout.get(t)}
    return "; ".join(f"{k}: {v}" for k, v in css.items())


def _output(out: dict) -> str:
    data = out.get("data", {})
    if "image/png" in data:
        alt = html.escape(str(data.get("text/plain", "figure")))
        return f'<img src="data:image/png;base64,{data["image/png"]}" alt="{alt}"/>'
    if "text/html" in data:
        return "".join(data["text/html"])
    text = out.get("text", "") if out.get("output_type") == "stream" else data.get("text/plain")
    return f"<pre>{html.escape(''.join(text))}</pre>" if text is not None else ""


def widget_html(state: dict, model_id: str) -> str:
    """Static HTML of one widget and its children.

    Parameters
    ----------
    state : dict
        The notebook's widget state, model id -> ``{"model_name", "state"}`` (the ``state``
        of ``application/vnd.jupyter.widget-state+json``).
    model_id : str
        The widget to draw.

    Returns
    -------
    str
        HTML; a widget kind not drawn here shows its name in brackets, never nothing.
    """
    model = state.get(model_id)
    if model is None:
        return f"<em>[widget {html.escape(model_id)}: no saved state]</em>"
    name, s = model["model_name"], model["state"]
    desc = html.escape(str(s.get("description", "")))

    def kids() -> str:
        return "".join(widget_html(state, c[len("IPY_MODEL_"):]) for c in s.get("children", ())
                       if isinstance(c, str) and c.startswith("IPY_MODEL_"))

    def div(inner: str, extra: dict | None = None) -> str:
        return f'<div class="sunlab-widget" style="{_css(state, model, extra)}">{inner}</div>'

    if name in BOXES:
        return div(kids(), {"display": "flex", "flex-direction": BOXES[name], "gap": "4px"})
    if name == "GridBoxModel":
        return div(kids(), {"display": "grid"})
    if name == "OutputModel":
        return div("".join(_output(o) for o in s.get("outputs", ())))
    if name in ("HTMLModel", "HTMLMathModel"):
        return div(s.get("value", ""))
    if name == "LabelModel":
        return f"<span>{html.escape(str(s.get('value', '')))}</span>"
    if name in ("ButtonModel", "ToggleButtonModel"):
        look = _model(state, s.get("style")) or {"state": {}}
        extra = {"background": look["state"].get("button_color") or "#eee",
                 "color": look["state"].get("text_color") or "black",
                 "border": "1px solid #ccc"}
        if look["state"].get("text_decoration"):
            extra["text-decoration"] = look["state"]["text_decoration"]
        if name == "ToggleButtonModel" and s.get("value"):
            extra["border"] = "2px solid #333"
        title = html.escape(str(s.get("tooltip") or ""))
        return (f'<button disabled title="{title}" style="{_css(state, model, extra)}">'
                f"{desc}</button>")
    if name in ("DropdownModel", "SelectModel", "RadioButtonsModel", "ToggleButtonsModel"):
        labels, index = s.get("_options_labels", []), s.get("index")
        value = labels[index] if isinstance(index, int) and index < len(labels) else ""
        return f"<span>{desc} <select disabled><option>{html.escape(str(value))}</option>" \
               f"</select></span>"
    if name.endswith("SliderModel") or name.endswith("TextModel") or name == "CheckboxModel":
        return f"<span>{desc} <code>{html.escape(str(s.get('value')))}</code></span>"
    return f"<em>[{html.escape(name)}]</em>"


def install() -> None:
    """Draw myst-nb's widget views from the saved state instead of its CDN script."""
    from docutils import nodes
    from myst_nb.core import render

    def render_widget_view(self, data):
        view = data.string if isinstance(data.string, dict) else json.loads(data.string)
        metadata = self.renderer.nb_client.nb_metadata
        state = metadata.get("widgets", {}).get(render.WIDGET_STATE_MIMETYPE, {}).get("state", {})
        body = widget_html(state, view.get("model_id", ""))
        # wider than the page's column: it scrolls sideways rather than spill over the sidebar
        wrapper = '<div class="sunlab-widget-static" style="overflow-x: auto">'
        return [nodes.raw(text=f"{wrapper}{body}</div>", format="html")]

    render.NbElementRenderer.render_widget_view = render_widget_view
