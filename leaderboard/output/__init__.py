"""What a run writes.

Markdown, CSV and entry documents (``report``), the PNG plots (``plots``) and the web page ``index.html``
(``webpage``, made from the folder's files by ``page_data``, with the inline ``page_assets``).
"""
