// MathJax 3 for the theory and API pages (pymdownx.arithmatex wraps their math in
// span/div.arithmatex with \( \) and \[ \]) and for the notebooks (mkdocs-jupyter leaves their
// $...$ and $$...$$ as they are, inside div.jp-MarkdownOutput). Nothing else is typeset.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"], ["$", "$"]],
    displayMath: [["\\[", "\\]"], ["$$", "$$"]],
    processEscapes: true,
    processEnvironments: true
  },
  options: {ignoreHtmlClass: ".*|", processHtmlClass: "arithmatex|jp-MarkdownOutput"}
};
document$.subscribe(() => {
  if (MathJax.typesetPromise) { MathJax.typesetPromise(); }
});
