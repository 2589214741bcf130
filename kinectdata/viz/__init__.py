"""What a person looks at: skeleton animations and the dataset report.

- :mod:`.render`: 3-D and 2-D skeleton animations as MP4 (with the music) or GIF;
- :mod:`.plots`: the dataset report's figures;
- :mod:`.report`: the report as one self-contained HTML page.
"""
